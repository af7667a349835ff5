#!/usr/bin/env python3
# v4r - robust model-based object tracking. MIT licence.
"""A client of `v4r serve` (docs/protocol.md) using only the Python standard library.

As a library:

    from v4r_client import V4rClient
    with V4rClient("127.0.0.1", 5757) as c:
        c.request("AddObject name=box")
        c.add_model("box", open("box.cao", "rb").read())
        c.request("SetPose object=box t=0,0,0.6 r=0,0,0")
        c.request("Subscribe what=ObjectPose")
        c.request("Start")
        for ev in c.events():
            print(ev["object"], ev["frame"], ev["t"], ev["status"])

As a program (tracks one object and prints its poses):

    python3 v4r_client.py --model box.cao --pose "0 0 0.6 0 0 0" --start --frames 100
"""

import argparse
import socket
import sys


class ProtocolError(Exception):
    """An `ERR` reply, or a connection problem."""


class V4rClient:
    """One connection to `v4r serve`: commands with their replies, and events."""

    def __init__(self, host="127.0.0.1", port=5757, timeout=10.0, token=None):
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.file = self.sock.makefile("rb")
        self.pending = []  # events that arrived while waiting for a reply
        self.greeting = self._read_line()
        if not self.greeting.startswith("Hello "):
            raise ProtocolError(self.greeting)
        if token is not None or "auth=required" in self.greeting:
            if token is None:
                raise ProtocolError("the server requires a token (Auth)")
            self.request("Auth token=" + token)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        try:
            self.sock.sendall(b"Quit\n")
        except OSError:
            pass
        self.file.close()
        self.sock.close()

    def _read_line(self):
        line = self.file.readline()
        if not line:
            raise ProtocolError("connection closed by the server")
        return line.decode("ascii", "replace").rstrip("\r\n")

    @staticmethod
    def _is_reply(line):
        return line.startswith("OK ") or line.startswith("ERR ") or line in ("OK", "ERR")

    def _wait_reply(self):
        while True:
            line = self._read_line()
            if self._is_reply(line):
                if line.startswith("ERR"):
                    raise ProtocolError(line)
                return line
            self.pending.append(line)

    def request(self, line):
        """Sends one command line and returns its `OK` reply (raises ProtocolError on `ERR`)."""
        self.sock.sendall(line.encode("ascii") + b"\n")
        return self._wait_reply()

    def add_model(self, obj, data, fmt="cao", scale=1.0):
        """`AddModel object=OBJ format=FMT [scale=S] bytes=N` followed by the model file's bytes;
        scale: model units to metres (0.001 for a model in millimetres)."""
        if isinstance(data, str):
            data = data.encode("utf-8")
        extra = b"" if scale == 1.0 else b" scale=%s" % repr(float(scale)).encode()
        self.sock.sendall(b"AddModel object=%s format=%s%s bytes=%d\n" % (obj.encode(), fmt.encode(), extra, len(data))
                          + data)
        return self._wait_reply()

    def set_pose(self, obj, t, r):
        """T_cam_obj: translation t (metres) and rotation vector r (radians)."""
        return self.request("SetPose object=%s t=%s r=%s" % (obj, _vec(t), _vec(r)))

    def events(self):
        """Yields events as dicts: ObjectPose (object, frame, stamp, t, q, cov, quality, status)
        and SystemStatus (frame, cycle_ms, ...); `type` names the event."""
        while True:
            line = self.pending.pop(0) if self.pending else self._read_line()
            ev = parse_event(line)
            if ev is not None:
                yield ev


def _vec(v):
    return ",".join(repr(float(x)) for x in v)


def parse_event(line):
    """An event line as a dict, or None for anything else. Unknown keys are kept as text."""
    words = line.split(" ")
    if not words or words[0] not in ("ObjectPose", "SystemStatus"):
        return None
    ev = {"type": words[0]}
    for w in words[1:]:
        key, _, value = w.partition("=")
        if key in ("t", "q", "cov"):
            ev[key] = [float(x) for x in value.split(",")]
        elif key in ("frame", "features_found", "features_used", "outliers", "overruns"):
            ev[key] = int(value)
        elif key in ("stamp", "quality", "cycle_ms"):
            ev[key] = float(value)
        else:
            ev[key] = value
    return ev


def main():
    ap = argparse.ArgumentParser(description="Track one object with `v4r serve` and print its poses.")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=5757)
    ap.add_argument("--token", default=None)
    ap.add_argument("--object", default="object")
    ap.add_argument("--model", required=True, help=".cao (or .obj/.ply/.stl) file sent inline")
    ap.add_argument("--model-units", choices=["mm", "cm", "m"], default="m", help="units of the model file")
    ap.add_argument("--pose", required=True, help='initial T_cam_obj "tx ty tz rx ry rz" (m, rad)')
    ap.add_argument("--start", action="store_true", help="send Start (for a server started with --paused)")
    ap.add_argument("--frames", type=int, default=0, help="stop after this many poses (0: run until closed)")
    args = ap.parse_args()

    pose = [float(x) for x in args.pose.replace(",", " ").split()]
    if len(pose) != 6:
        ap.error("--pose needs six numbers")
    fmt = args.model.rsplit(".", 1)[-1].lower()
    with open(args.model, "rb") as f:
        data = f.read()
    try:
        with V4rClient(args.host, args.port, token=args.token) as c:
            # The object is this client's: removed when it disconnects, so that a second run can add it again.
            c.request("AddObject name=%s lifetime=connection" % args.object)
            print(c.add_model(args.object, data, fmt, {"mm": 0.001, "cm": 0.01, "m": 1.0}[args.model_units]))
            c.set_pose(args.object, pose[:3], pose[3:])
            c.request("Subscribe what=ObjectPose")
            if args.start:
                c.request("Start")
            n = 0
            for ev in c.events():
                if ev["type"] != "ObjectPose" or ev["object"] != args.object:
                    continue
                t = ev["t"]
                print("frame %d  t = %.4f %.4f %.4f m  quality %.2f  %s" % (ev["frame"], t[0], t[1], t[2], ev["quality"],
                                                                              ev["status"]))
                n += 1
                if args.frames and n >= args.frames:
                    break
    except (ProtocolError, OSError) as e:
        print("v4r_client: %s" % e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
