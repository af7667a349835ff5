#!/usr/bin/env python3
# v4r - robust model-based object tracking. MIT licence.
"""`v4r serve --scene` through the real binary: a scene file of two cameras (both given the same
rendered sequence, so that the ground truth holds in each) and one object with its init_pose.
Every frame's ObjectPose is within 5 mm / 1 degree of the truth and names the reference frame
(ref=rig); every SystemStatus reports both cameras with the frames read so far.
(The stereo pair with a 12 cm baseline: libs/server/tests/scene_server_test.cpp.)

usage: serve_scene_test.py --v4r build/bin/v4r
"""
import argparse
import math
import re
import socket
import subprocess
import tempfile

FRAMES = 20


def quat_angle_deg(a, b):
    d = abs(sum(x * y for x, y in zip(a, b)))
    return math.degrees(2.0 * math.acos(min(1.0, d)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--v4r", required=True)
    v4r = ap.parse_args().v4r
    with tempfile.TemporaryDirectory() as cwd:
        subprocess.run([v4r, "render", "--model", "box", "--frames", str(FRAMES), "--output", "seq"], cwd=cwd,
                       check=True, stdout=subprocess.DEVNULL)
        truth = {}
        for row in open(cwd + "/seq/gt.csv").read().splitlines()[1:]:
            v = [float(x) for x in row.split(",")]
            truth[int(v[0])] = (v[1:4], v[4:8])
        pose = open(cwd + "/seq/init_pose.txt").read().split("\n")[1].split()
        with open(cwd + "/scene.yaml", "w") as f:
            f.write("reference_frame: rig\ncameras:\n")
            for name in ("cam_a", "cam_b"):
                f.write(f"  - name: {name}\n    calibration: seq/camera.yaml\n    input: seq/frames\n")
            f.write("objects:\n  - name: box\n    model: seq/model.cao\n    init_pose: [" + ", ".join(pose) + "]\n")
        srv = subprocess.Popen([v4r, "serve", "--scene", "scene.yaml", "--paused", "--port", "0"], cwd=cwd,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            first = srv.stdout.readline()
            m = re.search(r"protocol on [^:]+:(\d+)", first)
            assert m, first
            sock = socket.create_connection(("127.0.0.1", int(m.group(1))), timeout=30)
            f = sock.makefile("rb")
            assert f.readline().decode().startswith("Hello "), "no greeting"
            sock.sendall(b"Subscribe what=ObjectPose\nSubscribe what=SystemStatus\nStart\n")
            poses, status = {}, {}
            while len(poses) < FRAMES or len(status) < FRAMES:
                line = f.readline().decode().strip()
                assert line, "connection closed"
                frame = re.search(r"\bframe=(\d+)", line)
                if line.startswith("ObjectPose "):
                    poses[int(frame.group(1))] = line
                elif line.startswith("SystemStatus "):
                    status[int(frame.group(1))] = line
            worst_t, worst_r = 0.0, 0.0
            for k, line in poses.items():
                assert " ref=rig" in line, line
                t = [float(x) for x in re.search(r"\bt=(\S+)", line).group(1).split(",")]
                q = [float(x) for x in re.search(r"\bq=(\S+)", line).group(1).split(",")]
                worst_t = max(worst_t, math.dist(t, truth[k][0]))
                worst_r = max(worst_r, quat_angle_deg(q, truth[k][1]))
            for k, line in status.items():
                assert f" cameras=cam_a:{k + 1}:1,cam_b:{k + 1}:1" in line, line
            print(f"serve --scene: {len(poses)} frames, worst {worst_t * 1e3:.2f} mm, {worst_r:.3f} deg")
            assert worst_t < 0.005 and worst_r < 1.0, (worst_t, worst_r)
        finally:
            srv.terminate()
            srv.wait(timeout=30)
    print("ok")


if __name__ == "__main__":
    main()
