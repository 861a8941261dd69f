#!/usr/bin/env python3
"""A WLAN in user space: the switch of a test's private LAN of network namespaces, as an
Ethernet hub that delays, loses and cuts frames per host link (this kernel has no netem).

Run inside the switch namespace, it creates one TAP device per port (``--tap NAME``),
which the test then moves into a host's namespace as that host's LAN interface (a TAP
carries whole frames with their checksums computed: a veth's checksum and segmentation
offloads would hand a relay frames the next host drops). Every frame one host sends is
written to every other port, after passing the
*uplink* of its source port and the *downlink* of each destination port, each with that
port's profile (a frame between two hosts crosses two radio hops, as through an access
point). Frames keep their order per destination port (delay jitter does not reorder).

Profiles (``profile PORT NAME``):

- ``clean``: nothing added;
- ``wlan_good``: 2-5 ms per hop, 0.5 % loss;
- ``wlan_bad``: 20 +/- 10 ms per hop, 2 % loss;
- ``wlan_poor``: 20-80 ms per hop, 10 % loss in bursts (Gilbert-Elliott: 0 % / 50 %,
  bad spells of 0.2 s every 2 s on average);
- ``bursts``: Gilbert-Elliott, 1 % loss in the good state and 30 % in the bad one, bad
  spells of 1.5 s every 8.5 s on average (interference);
- ``5g``: 10-30 ms per hop, 0.1 % loss;
- ``down``: every frame lost (the host's link is cut).

``flap PORT DOWN_S EVERY_S`` cuts the port for DOWN_S seconds every EVERY_S seconds, the
first cut at once, over whatever profile it has; ``flap PORT 0 0`` stops it. ``cut PORT 1``
cuts it until ``cut PORT 0``, its profile kept. ``stats``
answers the frames seen, passed and lost per port; ``quit`` ends the relay.

Commands come one per line on a Unix socket (``--control PATH``), each answered with one
JSON line (``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``). The relay prints
``ready`` once its ports are open. Randomness is seeded (``--seed``).
"""

import argparse
import fcntl
import heapq
import json
import os
import random
import select
import socket
import struct
import sys
import time


class Hop:
    """One direction of one port's link: delay, loss and the Gilbert-Elliott state."""

    def __init__(self, rng):
        self.rng = rng
        self.set("clean")
        self.bad = False
        self.switch_at = 0.0

    def set(self, name):
        # (min delay s, max delay s, loss good, loss bad, mean good s, mean bad s)
        table = {
            "clean": (0.0, 0.0, 0.0, 0.0, None, None),
            "wlan_good": (0.002, 0.005, 0.005, 0.005, None, None),
            "wlan_bad": (0.010, 0.030, 0.02, 0.02, None, None),
            "wlan_poor": (0.020, 0.080, 0.0, 0.5, 1.8, 0.2),
            "bursts": (0.001, 0.003, 0.01, 0.30, 8.5, 1.5),
            "5g": (0.010, 0.030, 0.001, 0.001, None, None),
            "down": (0.0, 0.0, 1.0, 1.0, None, None),
        }
        if name not in table:
            raise ValueError(f"no profile `{name}` ({', '.join(table)})")
        self.name = name
        (self.dmin, self.dmax, self.loss_good, self.loss_bad, self.mean_good,
         self.mean_bad) = table[name]
        self.bad = False
        self.switch_at = 0.0

    def passes(self, now):
        """Whether a frame gets through at `now`, and its delay (s)."""
        if self.mean_good is not None:
            if self.switch_at == 0.0:  # the profile starts in the good state
                self.bad = False
                self.switch_at = now + self.rng.expovariate(1.0 / self.mean_good)
            while now >= self.switch_at:
                self.bad = not self.bad
                mean = self.mean_bad if self.bad else self.mean_good
                self.switch_at += self.rng.expovariate(1.0 / mean)
        loss = self.loss_bad if self.bad else self.loss_good
        if loss > 0.0 and self.rng.random() < loss:
            return False, 0.0
        return True, self.rng.uniform(self.dmin, self.dmax)


TUNSETIFF = 0x400454CA
IFF_TAP = 0x0002
IFF_NO_PI = 0x1000


class Port:
    def __init__(self, name, rng):
        self.name = name
        self.fd = os.open("/dev/net/tun", os.O_RDWR | os.O_NONBLOCK)
        fcntl.ioctl(self.fd, TUNSETIFF, struct.pack("16sH", name.encode(), IFF_TAP | IFF_NO_PI))
        self.up = Hop(rng)
        self.down = Hop(rng)
        self.flap = None  # (start, down_s, every_s)
        self.held_down = False
        self.last_out = 0.0
        self.seen = self.passed = self.lost = 0

    def cut(self, now):
        if self.held_down:
            return True
        if not self.flap:
            return False
        start, down_s, every_s = self.flap
        return (now - start) % every_s < down_s

    def stats(self):
        return {"profile": self.up.name, "flap": self.flap and list(self.flap[1:]),
                "cut": self.held_down,
                "seen": self.seen, "passed": self.passed, "lost": self.lost}


def command(line, ports):
    words = line.split()
    if not words:
        raise ValueError("empty command")
    if words[0] == "profile" and len(words) == 3:
        p = ports[words[1]]
        p.up.set(words[2])
        p.down.set(words[2])
        return {}
    if words[0] == "flap" and len(words) == 4:
        p = ports[words[1]]
        down_s, every_s = float(words[2]), float(words[3])
        if down_s <= 0.0 or every_s <= 0.0:
            p.flap = None
        elif down_s >= every_s:
            raise ValueError("flap: DOWN_S must be shorter than EVERY_S")
        else:
            p.flap = (time.monotonic(), down_s, every_s)
        return {}
    if words[0] == "cut" and len(words) == 3 and words[2] in ("0", "1"):
        ports[words[1]].held_down = words[2] == "1"
        return {}
    if words[0] == "stats":
        return {"ports": {n: p.stats() for n, p in ports.items()}}
    if words[0] == "quit":
        raise SystemExit(0)
    raise ValueError(f"unknown command `{line.strip()}`")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tap", action="append", required=True, help="TAP device to create and relay")
    ap.add_argument("--control", required=True, help="Unix socket path for commands")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    ports = {n: Port(n, rng) for n in args.tap}
    by_fd = {p.fd: p for p in ports.values()}
    if os.path.exists(args.control):
        os.unlink(args.control)
    ctl = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    ctl.bind(args.control)
    ctl.listen(4)
    ctl.setblocking(False)
    clients = {}
    queue = []  # (send at, seq, port, frame)
    seq = 0
    print("ready", flush=True)
    while True:
        now = time.monotonic()
        timeout = max(0.0, queue[0][0] - now) if queue else 0.5
        fds = [ctl] + [p.fd for p in ports.values()] + list(clients)
        readable, _, _ = select.select(fds, [], [], timeout)
        now = time.monotonic()
        for r in readable:
            if r is ctl:
                c, _ = ctl.accept()
                clients[c] = b""
                continue
            if r in clients:
                data = r.recv(4096)
                if not data:
                    clients.pop(r)
                    r.close()
                    continue
                clients[r] += data
                while b"\n" in clients[r]:
                    line, clients[r] = clients[r].split(b"\n", 1)
                    try:
                        answer = {"ok": True, **command(line.decode(), ports)}
                    except (KeyError, ValueError) as e:
                        answer = {"ok": False, "error": str(e)}
                    r.sendall((json.dumps(answer) + "\n").encode())
                continue
            src = by_fd[r]
            while True:
                try:
                    frame = os.read(src.fd, 65536)
                except (BlockingIOError, OSError):
                    break  # drained (or the interface is not up yet)
                if not frame:
                    break
                src.seen += 1
                ok, d_up = src.up.passes(now)
                if not ok or src.cut(now):
                    src.lost += 1
                    continue
                src.passed += 1
                for dst in ports.values():
                    if dst is src:
                        continue
                    ok, d_down = dst.down.passes(now)
                    if not ok or dst.cut(now):
                        dst.lost += 1
                        continue
                    at = max(now + d_up + d_down, dst.last_out)
                    dst.last_out = at
                    seq += 1
                    heapq.heappush(queue, (at, seq, dst, frame))
        while queue and queue[0][0] <= now:
            _, _, dst, frame = heapq.heappop(queue)
            if dst.cut(now):
                dst.lost += 1
                continue
            try:
                os.write(dst.fd, frame)
            except OSError:
                dst.lost += 1  # its interface is down (a cut link) or not up yet


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except KeyboardInterrupt:
        sys.exit(0)
