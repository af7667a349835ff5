#!/usr/bin/python3
# v4r - robust model-based object tracking. MIT licence.
"""The development benchmark without an initial pose (issue 10).

Runs `v4r track` on each sequence of ../shared/bench's development split with no --init-pose,
so that the object search finds the object itself, and prints per sequence:
  lock    the first frame whose status is `tracking` with a pose within 5 cm / 5 deg of the truth,
          modulo the model's symmetries (-1: never);
  after   the share of the frames from the lock on that are `tracking` or `degraded` within
          5 cm / 5 deg;
  false   frames that say `tracking` with a pose farther off (before or after the lock).

The symmetries are the rotations about the model's bounding-box centre (the 24 axis-aligned ones
and the turns about each axis by 360/k degrees, k = 2 .. 12) that map the .cao's points onto
themselves within 0.1 mm. (The shared eval_lock.py ignores them: a box found turned half about its
axis is a right pose.)

    /usr/bin/python3 bench/noinit_eval.py --data /tmp/v4r-bench [--only box_] [--jobs 2] [--set k=v]
"""
import argparse
import concurrent.futures
import csv
import itertools
import math
import os
import subprocess
import sys

import numpy as np

from honest_state_eval import CONDITIONS, OBJECTS, quat_to_R

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cao_points(path):
    """The points of a .cao file that its lines, faces, cylinder axes and circle centres use (a
    circle's points on its rim would break the symmetry of a round part)."""
    rows = []
    with open(path) as f:
        for line in f:
            line = line.split('#', 1)[0].strip()
            if line:
                rows.append(line.split())
    if not rows or rows[0][0].upper() != 'V1':
        raise ValueError(f'{path}: not a .cao file (no V1 line)')
    n = int(rows[1][0])
    pts = np.array([[float(v) for v in rows[2 + i][:3]] for i in range(n)])
    k = 2 + n
    used = set()
    n_lines = int(rows[k][0])
    for r in rows[k + 1:k + 1 + n_lines]:
        used.update(int(v) for v in r[:2])
    k += 1 + n_lines
    k += 1 + int(rows[k][0])  # faces from lines: their lines are counted above
    n_faces = int(rows[k][0])
    for r in rows[k + 1:k + 1 + n_faces]:
        used.update(int(v) for v in r[1:1 + int(r[0])])
    k += 1 + n_faces
    if k < len(rows):  # cylinders: axis points, radius
        n_cyl = int(rows[k][0])
        for r in rows[k + 1:k + 1 + n_cyl]:
            used.update(int(v) for v in r[:2])
        k += 1 + n_cyl
    if k < len(rows):  # circles: radius, centre, two points on it
        for r in rows[k + 1:k + 1 + int(rows[k][0])]:
            used.add(int(r[1]))
    return pts[sorted(used)] if used else pts


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def symmetries(points, tol=1e-4):
    """4x4 transforms S (object frame) with S * points == points as a set, the identity first."""
    centre = 0.5 * (points.min(0) + points.max(0))
    cands = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            r = np.zeros((3, 3))
            for i, j in enumerate(perm):
                r[i, j] = signs[i]
            if np.linalg.det(r) > 0:
                cands.append(r)
    for axis in np.eye(3):
        for k in range(2, 13):
            cands += [rot(axis, 2 * math.pi * j / k) for j in range(1, k)]
    found = []
    for r in cands:
        q = (points - centre) @ r.T + centre
        d = np.linalg.norm(q[:, None, :] - points[None, :, :], axis=2).min(1)
        if d.max() < tol and not any(np.allclose(r, f[:3, :3], atol=1e-6) for f in found):
            s = np.eye(4)
            s[:3, :3] = r
            s[:3, 3] = centre - r @ centre
            found.append(s)
    return found


def pose(row, keys=('tx', 'ty', 'tz', 'qw', 'qx', 'qy', 'qz')):
    v = [float(row[k]) for k in keys]
    t = np.eye(4)
    t[:3, :3] = quat_to_R(np.array(v[3:]))
    t[:3, 3] = v[:3]
    return t


def error(t_est, t_gt, syms):
    """Smallest (metres, degrees) over the symmetric equivalents of t_est."""
    best = (1e9, 1e9)
    for s in syms:
        e = t_est @ s
        dt = np.linalg.norm(e[:3, 3] - t_gt[:3, 3])
        c = (np.trace(e[:3, :3].T @ t_gt[:3, :3]) - 1) / 2
        da = math.degrees(math.acos(max(-1.0, min(1.0, c))))
        if max(dt / 0.05, da / 5.0) < max(best[0] / 0.05, best[1] / 5.0):
            best = (dt, da)
    return best


def run(seq_dir, args):
    out = os.path.join(seq_dir, args.csv)
    cmd = [args.v4r, 'track', '--model', os.path.join(seq_dir, 'model.cao'), '--camera',
           os.path.join(seq_dir, 'camera.yaml'), '--input', os.path.join(seq_dir, 'frames'), '--output', out]
    for kv in args.set or []:
        cmd += ['--set', kv]
    with open(out + '.log', 'w') as log:
        rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
    if rc != 0:
        return None
    syms = symmetries(cao_points(os.path.join(seq_dir, 'model.cao')))  # the identity among them
    with open(os.path.join(seq_dir, 'gt_poses.csv')) as f:
        gt = {int(r['frame']): pose(r) for r in csv.DictReader(f)}
    lock, ok_after, n_after, false = -1, 0, 0, 0
    with open(out) as f:
        for r in csv.DictReader(f):
            k = int(r['frame'])
            good = False
            if r['status'] in ('tracking', 'degraded') and r['tx'] != '':
                dt, da = error(pose(r), gt[k], syms)
                good = dt <= 0.05 and da <= 5.0
                false += 0 if good or r['status'] != 'tracking' else 1
            if lock < 0 and good and r['status'] == 'tracking':
                lock = k
            if lock >= 0:
                n_after += 1
                ok_after += 1 if good else 0
    return lock, (100.0 * ok_after / n_after if n_after else 0.0), false, len(syms)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--data', default='/tmp/v4r-bench')
    ap.add_argument('--v4r', default=os.path.join(REPO, 'build', 'bin', 'v4r'))
    ap.add_argument('--only', action='append', help='sequences whose name contains this (repeatable)')
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--set', action='append', help='v4r track --set key=value (repeatable)')
    ap.add_argument('--csv', default='noinit.csv', help="name of v4r's pose CSV in each sequence folder")
    args = ap.parse_args()
    seqs = [f'{o}_{c}' for o in OBJECTS for c in CONDITIONS]
    seqs = [s for s in seqs if not args.only or any(p in s for p in args.only)]
    missing = [s for s in seqs if not os.path.exists(os.path.join(args.data, s, 'gt_poses.csv'))]
    if missing:
        sys.exit(f'{args.data}: missing {", ".join(missing)} (make them with ../shared/bench/make_sequences.py)')
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as ex:
        res = dict(zip(seqs, ex.map(lambda s: run(os.path.join(args.data, s), args), seqs)))
    print(f'{"sequence":20s} {"lock":>5s} {"after %":>8s} {"false":>6s} {"symm":>5s}')
    for s in seqs:
        r = res[s]
        if r is None:
            print(f'{s:20s} v4r track failed (see {os.path.join(args.data, s, args.csv)}.log)')
            continue
        print(f'{s:20s} {r[0]:5d} {r[1]:8.1f} {r[2]:6d} {r[3]:5d}')
    done = [r for r in res.values() if r is not None]
    print(f'locked by frame 10: {sum(1 for r in done if 0 <= r[0] <= 10)} of {len(seqs)}; '
          f'false tracking frames: {sum(r[2] for r in done)}')


if __name__ == '__main__':
    main()
