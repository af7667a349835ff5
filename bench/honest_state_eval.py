#!/usr/bin/python3
"""Honest state on the independent benchmark (issue 9): per sequence and per condition the mean
error, success (5 cm / 5 deg), sigma calibration (translation error within 3 sigma, median
|error|/sigma, per camera axis, frames reported tracking or degraded from frame 1), the status
rates, and the jitter of the static sequences.

  false lost:     frames reported `lost` while the reported pose is within 5 cm / 5 deg of truth
  false tracking: frames reported `tracking` while farther (or while the object is absent,
                  frame_info.csv present=0)

usage: honest_state_eval.py --bench /tmp/v4r-bench --v4r build/bin/v4r [--out DIR] [--only a,b]
       [--json results.json] [--set name=value ...]
Sequences: the 24 development sequences (OBJECT_CONDITION), static_* and recover_*.
Rows of `searching` frames (empty pose) count as neither false lost nor false tracking."""
import argparse, csv, json, math, os, subprocess, sys
import numpy as np

OBJECTS = ('box', 'mockup', 'flange')
CONDITIONS = ('regular', 'light', 'noise', 'clutter', 'occlusion', 'specular', 'blur', 'fast')


def quat_to_R(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def rot_deg(q1, q2):
    return math.degrees(2 * math.acos(min(1.0, abs(float(np.dot(q1 / np.linalg.norm(q1), q2 / np.linalg.norm(q2)))))))


def load_gt(path):
    gt = {}
    for r in csv.DictReader(open(path)):
        gt[int(float(r['frame']))] = (np.array([float(r[c]) for c in ('tx', 'ty', 'tz')]),
                                      np.array([float(r[c]) for c in ('qw', 'qx', 'qy', 'qz')]))
    return gt


def load_est(path):
    est = {}
    for r in csv.DictReader(open(path)):
        try:
            k = int(float(r['frame']))
        except (KeyError, ValueError, TypeError):
            continue
        status = (r.get('status') or '').strip()
        try:
            t = np.array([float(r[c]) for c in ('tx', 'ty', 'tz')])
            q = np.array([float(r[c]) for c in ('qw', 'qx', 'qy', 'qz')])
        except (KeyError, ValueError, TypeError):
            est[k] = (None, None, None, status)
            continue
        try:
            s = np.array([float(r[c]) for c in ('sigma_tx', 'sigma_ty', 'sigma_tz')])
        except (KeyError, ValueError, TypeError):
            s = None
        est[k] = (t, q, s, status)
    return est


def load_present(seq_dir):
    path = os.path.join(seq_dir, 'frame_info.csv')
    if not os.path.exists(path):
        return {}
    return {int(r['frame']): r.get('present', '1').strip() != '0' for r in csv.DictReader(open(path))}


def evaluate(seq_dir, est_path):
    gt, est, present = load_gt(os.path.join(seq_dir, 'gt_poses.csv')), load_est(est_path), load_present(seq_dir)
    frames = sorted(gt)[1:]
    et, ok5, z, false_lost, false_tracking, lost, tracking, absent_tracking = [], 0, [], 0, 0, 0, 0, 0
    ts, qs = [], []
    for k in frames:
        here = present.get(k, True)
        if k not in est or est[k][0] is None:
            if here:
                et.append(float('nan'))
            continue
        t, q, s, status = est[k]
        if not here:
            absent_tracking += status == 'tracking'
            continue
        e_t = 1000 * float(np.linalg.norm(t - gt[k][0]))
        e_r = rot_deg(q, gt[k][1])
        near = e_t < 50 and e_r < 5
        et.append(e_t)
        ok5 += near
        lost += status == 'lost'
        tracking += status == 'tracking'
        false_lost += status == 'lost' and near
        false_tracking += status == 'tracking' and not near
        if status in ('tracking', 'degraded') and s is not None and np.all(s > 0):
            z += list(np.abs(t - gt[k][0]) / s)
        if k > 10:
            ts.append(t); qs.append(q)
    fin = [e for e in et if math.isfinite(e)]
    n_here = sum(1 for k in frames if present.get(k, True))
    out = dict(frames=len(frames), mean_t_mm=round(float(np.mean(fin)), 3) if fin else None,
               success=round(ok5 / max(1, n_here), 4), lost=lost, tracking=tracking, false_lost=false_lost,
               false_tracking=false_tracking + absent_tracking, absent_tracking=absent_tracking,
               z=z)
    if ts:
        ts = np.array(ts)
        out['t_std_mm'] = round(1000 * float(np.sqrt(ts.var(axis=0).max())), 4)
        ref = qs[-1]
        out['r_std_deg'] = round(float(np.sqrt(np.mean([rot_deg(q, ref) ** 2 for q in qs]))), 4)
    return out


def calib(z):
    z = np.array(z)
    if len(z) == 0:
        return None, None
    return round(float((z <= 3).mean()), 4), round(float(np.median(z)), 3)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bench', default='/tmp/v4r-bench')
    ap.add_argument('--v4r', default='build/bin/v4r')
    ap.add_argument('--out', default='/tmp/honest_state_eval')
    ap.add_argument('--only', default='')
    ap.add_argument('--json', default='')
    ap.add_argument('--set', action='append', default=[], help='tracker parameter NAME=VALUE (repeatable)')
    ap.add_argument('--no-run', action='store_true', help='evaluate the CSVs already in --out')
    a = ap.parse_args()
    seqs = [f'{o}_{c}' for o in OBJECTS for c in CONDITIONS] + [f'static_{o}' for o in OBJECTS] + \
           [f'recover_{o}' for o in OBJECTS]
    if a.only:
        keep = a.only.split(',')
        seqs = [s for s in seqs if any(k in s for k in keep)]
    os.makedirs(a.out, exist_ok=True)
    results = {}
    for s in seqs:
        d = os.path.join(a.bench, s)
        if not os.path.isdir(d):
            print(f'{s}: missing, skipped', file=sys.stderr)
            continue
        est = os.path.join(a.out, s + '.csv')
        if not a.no_run:
            subprocess.run([a.v4r, 'track', '--model', os.path.join(d, 'model.cao'), '--camera',
                            os.path.join(d, 'camera.yaml'), '--input', os.path.join(d, 'frames'),
                            '--init-pose-file', os.path.join(d, 'init_pose.txt'), '--output', est,
                            '--no-warnings'] + sum((['--set', x] for x in a.set), []), check=True, stdout=subprocess.DEVNULL)
        results[s] = evaluate(d, est)
    print(f'{"sequence":20s} {"mean mm":>8s} {"succ%":>6s} {"in3s%":>6s} {"med z":>6s} {"lost":>5s} '
          f'{"fLost":>5s} {"fTrk":>5s} {"t std":>7s} {"r std":>7s}')
    for s, r in results.items():
        w3, mz = calib(r['z'])
        print(f'{s:20s} {r["mean_t_mm"] if r["mean_t_mm"] is not None else float("nan"):8.3f} '
              f'{100 * r["success"]:6.1f} {100 * w3 if w3 is not None else float("nan"):6.1f} '
              f'{mz if mz is not None else float("nan"):6.2f} {r["lost"]:5d} {r["false_lost"]:5d} '
              f'{r["false_tracking"]:5d} '
              + (f'{r["t_std_mm"]:7.4f} {r["r_std_deg"]:7.4f}' if s.startswith('static_') else ''))
    print('\nper condition (development sequences; false rates as a share of the frames the object is in view):')
    groups = {c: [f'{o}_{c}' for o in OBJECTS] for c in CONDITIONS}
    groups['static'] = [f'static_{o}' for o in OBJECTS]
    groups['recover'] = [f'recover_{o}' for o in OBJECTS]
    print(f'{"condition":12s} {"in3s%":>6s} {"med z":>6s} {"false lost":>12s} {"false tracking":>15s} {"absent trk":>10s}')
    allz = []
    for c, members in groups.items():
        rs = [results[m] for m in members if m in results]
        if not rs:
            continue
        z = sum((r['z'] for r in rs), [])
        allz += z
        w3, mz = calib(z)
        n = sum(r['frames'] for r in rs)
        fl = sum(r['false_lost'] for r in rs)
        ft = sum(r['false_tracking'] - r['absent_tracking'] for r in rs)
        at = sum(r['absent_tracking'] for r in rs)
        print(f'{c:12s} {100 * w3 if w3 is not None else float("nan"):6.1f} {mz if mz is not None else float("nan"):6.2f} '
              f'{fl:4d} ({100 * fl / n:4.1f}%) {ft:5d} ({100 * ft / n:5.1f}%) {at:10d}')
    w3, mz = calib(allz)
    print(f'{"all":12s} {100 * w3 if w3 is not None else float("nan"):6.1f} {mz if mz is not None else float("nan"):6.2f}')
    if a.json:
        json.dump({s: {k: v for k, v in r.items() if k != 'z'} | {'within3': calib(r['z'])[0], 'median_z': calib(r['z'])[1]}
                   for s, r in results.items()}, open(a.json, 'w'), indent=1)


if __name__ == '__main__':
    main()
