#!/usr/bin/env python3
"""An RTSP camera for tests: Debian's ffmpeg encodes H.264 (libx264) and sends it as RTP
to this server, which serves it to RTSP clients (RFC 2326) over TCP (interleaved) or UDP,
as a gimbal camera on a UAV's Ethernet does.

    rtsp_server.py [--port P] [--size 320x240] [--rate 10] [--image FILE]
                   [--corrupt-every N] [--garbage-after N]

ffmpeg's RTSP muxer only pushes to a server and its `-rtsp_flags listen` only receives, so
the serving side is this script: OPTIONS, DESCRIBE (the SDP ffmpeg wrote, with control
URLs), SETUP (`RTP/AVP/TCP;interleaved=` or `RTP/AVP;client_port=`), PLAY,
GET_PARAMETER (keep-alive), TEARDOWN; each RTP packet ffmpeg sends is forwarded to every
playing client. The source is ffmpeg's `testsrc` at `--size`/`--rate`, or `--image` (a
JPEG or PNG) looped at that rate. Faults for the tests: `--corrupt-every N` overwrites the
slice data of every Nth RTP packet (when it is a fragment of a slice) with noise (a
corrupt bitstream); `--garbage-after N`
writes bytes that are no RTSP message and no interleaved frame onto each TCP client's
connection after N packets (garbage on the socket).

Prints `RTSP_PORT <port>` once it listens (port 0 picks a free one); SIGTERM stops it
and its ffmpeg. Only the Python standard library.
"""

import argparse
import os
import random
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time


def bind_rtp_pair():
    """A UDP socket on an even port P with P+1 free too (ffmpeg sends RTCP there)."""
    for _ in range(100):
        rtp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rtp.bind(("127.0.0.1", 0))
        port = rtp.getsockname()[1]
        rtcp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            rtcp.bind(("127.0.0.1", port + 1))
        except OSError:
            rtp.close()
            rtcp.close()
            continue
        return rtp, rtcp
    raise SystemExit("rtsp_server: no free UDP port pair")


def start_ffmpeg(args, port, sdp_path):
    w, h = args.size.split("x")
    if args.image:
        source = ["-loop", "1", "-framerate", str(args.rate), "-i", args.image,
                  "-vf", f"scale={w}:{h}"]
    else:
        source = ["-f", "lavfi", "-i", f"testsrc=size={args.size}:rate={args.rate}"]
    cmd = (["ffmpeg", "-hide_banner", "-loglevel", "error", "-re"] + source +
           ["-an", "-c:v", "libx264", "-preset", "ultrafast", "-tune", "zerolatency",
            "-pix_fmt", "yuv420p", "-g", str(args.rate), "-bf", "0",
            "-f", "rtp", "-payload_type", "96", "-sdp_file", sdp_path,
            f"rtp://127.0.0.1:{port}?pkt_size=1200"])

    def die_with_parent():
        # PR_SET_PDEATHSIG = 1: ffmpeg gets SIGTERM when this server dies, however it dies.
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)

    return subprocess.Popen(cmd, preexec_fn=die_with_parent)


def read_sdp(path, ffmpeg):
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        if ffmpeg.poll() is not None:
            raise SystemExit(f"rtsp_server: ffmpeg exited with {ffmpeg.returncode}")
        try:
            text = open(path).read()
            if "a=rtpmap" in text:
                return text
        except FileNotFoundError:
            pass
        time.sleep(0.05)
    raise SystemExit("rtsp_server: ffmpeg wrote no SDP")


def described_sdp(ffmpeg_sdp):
    """The SDP a client gets: ffmpeg's media lines, with session and control attributes."""
    media = [l for l in ffmpeg_sdp.splitlines()
             if l.startswith(("a=rtpmap", "a=fmtp"))]
    return "\r\n".join(["v=0", "o=- 0 0 IN IP4 127.0.0.1", "s=skein test camera",
                        "c=IN IP4 0.0.0.0", "t=0 0", "a=control:*",
                        "m=video 0 RTP/AVP 96"] + media + ["a=control:track1", ""])


class Client:
    def __init__(self, conn):
        self.conn = conn
        self.lock = threading.Lock()
        self.playing = False
        self.udp_to = None
        self.channel = 0
        self.sent = 0
        self.garbage_sent = False

    def send(self, data):
        with self.lock:
            self.conn.sendall(data)


class Server:
    def __init__(self, args):
        self.args = args
        self.clients = []
        self.lock = threading.Lock()
        self.udp_out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp_out.bind(("127.0.0.1", 0))
        self.packets = 0

    def forward(self, rtp_sock):
        rng = random.Random(7)
        while True:
            packet = rtp_sock.recv(65536)
            self.packets += 1
            if (self.args.corrupt_every and self.packets % self.args.corrupt_every == 0
                    and len(packet) > 40 and packet[12] & 0x1F == 28 and not packet[13] & 0x80):
                # A middle or last fragment (FU-A, RFC 6184 §5.8) of a slice: the RTP and
                # FU headers kept (the packetisation stays valid), the slice data noise.
                packet = packet[:24] + bytes(rng.randrange(256) for _ in packet[24:])
            with self.lock:
                clients = [c for c in self.clients if c.playing]
            for c in clients:
                try:
                    if c.udp_to:
                        self.udp_out.sendto(packet, c.udp_to)
                    else:
                        c.send(b"$" + bytes([c.channel]) + len(packet).to_bytes(2, "big") + packet)
                        c.sent += 1
                        if (self.args.garbage_after and not c.garbage_sent
                                and c.sent >= self.args.garbage_after):
                            c.garbage_sent = True
                            c.send(b"\x17garbage\x00\xff" + bytes(rng.randrange(256) for _ in range(300)))
                except OSError:
                    c.playing = False

    def serve(self, conn, sdp, port):
        client = Client(conn)
        with self.lock:
            self.clients.append(client)
        buf = b""
        try:
            while True:
                while b"\r\n\r\n" not in buf:
                    chunk = conn.recv(4096)
                    if not chunk:
                        return
                    buf += chunk
                    # Interleaved RTCP from the client (receiver reports): skipped.
                    while buf.startswith(b"$") and len(buf) >= 4:
                        n = int.from_bytes(buf[2:4], "big")
                        if len(buf) < 4 + n:
                            break
                        buf = buf[4 + n:]
                head, buf = buf.split(b"\r\n\r\n", 1)
                lines = head.decode("latin-1").split("\r\n")
                method, url, _ = lines[0].split(" ", 2)
                headers = {}
                for l in lines[1:]:
                    k, _, v = l.partition(":")
                    headers[k.strip().lower()] = v.strip()
                body_len = int(headers.get("content-length", "0"))
                while len(buf) < body_len:
                    buf += conn.recv(4096)
                buf = buf[body_len:]
                reply = [f"CSeq: {headers.get('cseq', '0')}", "Server: skein-test-rtsp"]
                body = b""
                if method == "OPTIONS":
                    reply.append("Public: OPTIONS, DESCRIBE, SETUP, PLAY, TEARDOWN, GET_PARAMETER")
                elif method == "DESCRIBE":
                    body = described_sdp(sdp).encode()
                    base = url if url.endswith("/") else url + "/"
                    reply += [f"Content-Base: {base}", "Content-Type: application/sdp"]
                elif method == "SETUP":
                    t = headers.get("transport", "")
                    if "RTP/AVP/TCP" in t:
                        m = re.search(r"interleaved=(\d+)", t)
                        client.channel = int(m.group(1)) if m else 0
                        reply.append(f"Transport: RTP/AVP/TCP;unicast;interleaved="
                                     f"{client.channel}-{client.channel + 1}")
                    else:
                        m = re.search(r"client_port=(\d+)-(\d+)", t)
                        client.udp_to = ("127.0.0.1", int(m.group(1)))
                        sp = self.udp_out.getsockname()[1]
                        reply.append(f"Transport: RTP/AVP;unicast;client_port={m.group(1)}-"
                                     f"{m.group(2)};server_port={sp}-{sp + 1}")
                    reply.append("Session: 5f3a9c21;timeout=60")
                elif method == "PLAY":
                    reply.append("Session: 5f3a9c21")
                elif method in ("GET_PARAMETER", "SET_PARAMETER"):
                    reply.append("Session: 5f3a9c21")
                elif method == "TEARDOWN":
                    client.playing = False
                else:
                    client.send(f"RTSP/1.0 501 Not Implemented\r\n{reply[0]}\r\n\r\n".encode())
                    continue
                if body:
                    reply.append(f"Content-Length: {len(body)}")
                client.send(("RTSP/1.0 200 OK\r\n" + "\r\n".join(reply) + "\r\n\r\n").encode() + body)
                if method == "PLAY":
                    client.playing = True
                if method == "TEARDOWN":
                    return
        except (OSError, ValueError):
            return
        finally:
            client.playing = False
            with self.lock:
                self.clients.remove(client)
            conn.close()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--port", type=int, default=0)
    p.add_argument("--size", default="320x240")
    p.add_argument("--rate", type=int, default=10)
    p.add_argument("--image")
    p.add_argument("--corrupt-every", type=int, default=0)
    p.add_argument("--garbage-after", type=int, default=0)
    args = p.parse_args()

    rtp, _rtcp = bind_rtp_pair()
    tmp = tempfile.mkdtemp(prefix="skein-rtsp-")
    sdp_path = os.path.join(tmp, "stream.sdp")
    ffmpeg = start_ffmpeg(args, rtp.getsockname()[1], sdp_path)

    def stop(*_):
        ffmpeg.terminate()
        os._exit(0)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    sdp = read_sdp(sdp_path, ffmpeg)

    server = Server(args)
    threading.Thread(target=server.forward, args=(rtp,), daemon=True).start()
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind(("127.0.0.1", args.port))
    listener.listen(8)
    print(f"RTSP_PORT {listener.getsockname()[1]}", flush=True)
    threading.Thread(target=lambda: (ffmpeg.wait(), os._exit(3)), daemon=True).start()
    while True:
        conn, _ = listener.accept()
        threading.Thread(target=server.serve, args=(conn, sdp, args.port), daemon=True).start()


if __name__ == "__main__":
    sys.exit(main())
