#!/usr/bin/env python3
# v4r - robust model-based object tracking. MIT licence.
"""Units over the protocol: a millimetre OBJ with `AddModel ... scale=0.001` tracks as well as
the metre one, and `SetPose` refuses degrees and millimetres. Also the objects' lifetime: an
object outlives the client that added it unless added with `lifetime=connection`.

usage: serve_units_test.py --v4r build/bin/v4r
"""

import argparse
import csv
import os
import re
import socket
import subprocess
import sys
import tempfile
import time

FRAMES = 20


def box_obj(path, scale):
    """The built-in box (0.20 x 0.15 x 0.10 m, centred) as an OBJ, counter-clockwise from outside."""
    hx, hy, hz = 0.10 * scale, 0.075 * scale, 0.05 * scale
    v = [(-hx, -hy, -hz), (hx, -hy, -hz), (hx, hy, -hz), (-hx, hy, -hz),
         (-hx, -hy, hz), (hx, -hy, hz), (hx, hy, hz), (-hx, hy, hz)]
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
    with open(path, "w") as f:
        for p in v:
            f.write("v %.9g %.9g %.9g\n" % p)
        for a, b, c, d in quads:
            f.write("f %d %d %d\nf %d %d %d\n" % (a + 1, b + 1, c + 1, a + 1, c + 1, d + 1))


class Client:
    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=30)
        self.f = self.sock.makefile("rb")
        hello = self.line()
        assert hello.startswith("Hello "), hello
        self.events = []

    def line(self):
        return self.f.readline().decode().strip()

    def request(self, text):
        self.sock.sendall((text + "\n").encode())
        while True:
            r = self.line()
            if not r:
                raise SystemExit("connection closed after " + text)
            if r.startswith("OK ") or r.startswith("ERR "):
                return r
            self.events.append(r)

    def ok(self, text):
        r = self.request(text)
        if not r.startswith("OK "):
            raise SystemExit(f"{text} -> {r}")
        return r


def field(ev, key):
    m = re.search(r"\b" + key + r"=(\S+)", ev)
    return m.group(1) if m else None


def track(v4r, cwd, model, scale, checks):
    srv = subprocess.Popen([v4r, "serve", "--camera", "seq/camera.yaml", "--input", "seq/frames", "--paused",
                            "--port", "0"], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        first = srv.stdout.readline()
        port = int(re.search(r"protocol on [^:]+:(\d+)", first).group(1))
        c = Client(port)
        c.ok("AddObject name=part")
        extra = "" if scale == 1 else " scale=%g" % scale
        reply = c.ok("AddModel object=part path=" + model + extra)
        print(reply)
        pose = [float(x) for x in open(os.path.join(cwd, "seq/init_pose.txt")).read().split("\n")[1].split()]
        t = ",".join("%.9g" % x for x in pose[:3])
        r = ",".join("%.9g" % x for x in pose[3:])
        if checks:
            deg = ",".join("%.9g" % (x * 57.29577951308232) for x in pose[3:])
            bad = c.request("SetPose object=part t=" + t + " r=" + deg)
            print(bad)
            assert bad.startswith("ERR SetPose code=out_of_range") and "degrees?" in bad, bad
            mm = ",".join("%.9g" % (x * 1000) for x in pose[:3])
            bad = c.request("SetPose object=part t=" + mm + " r=" + r)
            print(bad)
            assert bad.startswith("ERR SetPose code=out_of_range") and "millimetres?" in bad, bad
            bad = c.request("AddModel object=part path=" + model + " scale=0")
            print(bad)
            assert bad.startswith("ERR AddModel code=out_of_range"), bad
        if checks:
            # Object lifetime: a server object outlives its client, a connection object does not.
            other = Client(port)
            other.ok("AddObject name=kept")
            other.ok("AddObject name=mine lifetime=connection")
            other.sock.sendall(b"Quit\n")
            other.sock.close()
            for _ in range(100):
                again = c.request("AddObject name=mine")
                if again.startswith("OK "):
                    break
                time.sleep(0.05)
            print(again)
            assert again.startswith("OK AddObject"), again
            kept = c.request("AddObject name=kept")
            print(kept)
            assert kept.startswith("ERR AddObject code=exists"), kept
            c.ok("RemoveObject name=kept")
            c.ok("RemoveObject name=mine")
        c.ok("SetPose object=part t=" + t + " r=" + r)
        c.ok("Subscribe what=ObjectPose")
        c.ok("Start")
        poses = {}
        while len(poses) < FRAMES:
            ev = c.events.pop(0) if c.events else c.line()
            if not ev:
                break
            if ev.startswith("ObjectPose "):
                frame = int(field(ev, "frame"))
                poses[frame] = ([float(x) for x in field(ev, "t").split(",")], field(ev, "status"))
        c.sock.close()
        return poses
    finally:
        srv.terminate()
        srv.wait(timeout=10)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--v4r", required=True)
    v4r = os.path.abspath(ap.parse_args().v4r)
    with tempfile.TemporaryDirectory(prefix="v4r_serve_units_") as cwd:
        subprocess.run([v4r, "render", "--model", "box", "--frames", str(FRAMES), "--output", "seq"], cwd=cwd,
                       check=True, stdout=subprocess.DEVNULL)
        box_obj(os.path.join(cwd, "box_m.obj"), 1.0)
        box_obj(os.path.join(cwd, "box_mm.obj"), 1000.0)
        gt = {int(row["frame"]): [float(row[k]) for k in ("tx", "ty", "tz")]
              for row in csv.DictReader(open(os.path.join(cwd, "seq/gt.csv")))}
        metre = track(v4r, cwd, "box_m.obj", 1.0, True)
        milli = track(v4r, cwd, "box_mm.obj", 0.001, False)
        assert len(metre) == FRAMES and len(milli) == FRAMES, (len(metre), len(milli))
        worst_m = worst_mm = worst_diff = 0.0
        for f in range(FRAMES):
            (tm, sm), (tmm, smm) = metre[f], milli[f]
            assert sm == "tracking" and smm == "tracking", (f, sm, smm)
            err = lambda a, b: max(abs(x - y) for x, y in zip(a, b))
            worst_m = max(worst_m, err(tm, gt[f]))
            worst_mm = max(worst_mm, err(tmm, gt[f]))
            worst_diff = max(worst_diff, err(tm, tmm))
        print("max translation error: metre OBJ %.2f mm, millimetre OBJ with scale=0.001 %.2f mm, "
              "difference %.4f mm" % (worst_m * 1e3, worst_mm * 1e3, worst_diff * 1e3))
        assert worst_m < 0.01 and worst_mm < 0.01, (worst_m, worst_mm)
        assert worst_diff < 1e-4, worst_diff
    print("ok")


if __name__ == "__main__":
    main()
