#!/usr/bin/python3
"""v4r against ViSP's edge tracker on the shared benchmark (development split) and ViSP's real cube.

    /usr/bin/python3 bench/compare_visp.py                        # all 24 sequences + the real cube
    /usr/bin/python3 bench/compare_visp.py --only flange_ --no-visp --set track.half_width=12
    /usr/bin/python3 bench/compare_visp.py --shared-bench /work/shared/bench --data /tmp/v4r-bench

What it does (run from anywhere; paths default relative to this repository):
1. generates the benchmark into --data (default /tmp/v4r-bench) if it holds none of the selected
   sequences: `make_sequences.py --out DATA --jobs 2` of --shared-bench (default ../shared/bench
   next to the repository); a folder holding only some of them is left alone and named (it may be
   another instance of the benchmark, which the generator would overwrite);
2. compiles bench/visp/visp_track.cpp with `g++ -O2 $(pkg-config --cflags --libs visp)` into
   build/visp/visp_track when the binary is missing or older than the source (needs libvisp-dev;
   ViSP is never linked into v4r);
3. on every sequence runs `build/bin/v4r track` (-> SEQ/v4r.csv, log SEQ/v4r.log) and ViSP
   (-> SEQ/visp.csv, cached: rerun only when missing, older than the binary, or with --rerun-visp;
   --no-visp never runs it), --jobs at a time (default 2);
4. evaluates both with `eval_poses.py GT EST --skip-first` and prints one table. With --starts K,
   v4r also runs from K - 1 more starts, each moved by at most 0.1 mm / 0.2 mrad (SEQ/v4r_startK.csv),
   and a last column gives the success over all K (mean [min-max]): under blur a start 0.1 um away
   can change a sequence by 20 points, so a change is judged on the mean, not on one start.

The real cube (Debian visp-images-data, mbt/cube, 218 frames) has no ground truth: its reference is
ViSP's trajectory committed as tests/data/visp_cube_reference.csv, so its ViSP column reads "ref"
(ViSP is re-run only to show its time). v4r starts from mbt/cube.0.pos.

ViSP's moving-edge settings are visp_track's defaults (mask 5x5 x 180 orientations, range +-7 px,
likelihood threshold 5000, mu1 = mu2 = 0.5, sample step 4 px, faces appear/disappear at 70/80 deg),
i.e. the configuration ViSP ships with its cube sequence; --visp-arg passes more (e.g.
--visp-arg=--range --visp-arg=12).
"""
import argparse
import concurrent.futures as cf
import json
import os
import random
import shutil
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OBJECTS = ['box', 'mockup', 'flange']
CONDITIONS = ['regular', 'light', 'noise', 'clutter', 'occlusion', 'specular', 'blur', 'fast']
SEQUENCES = ['%s_%s' % (o, c) for o in OBJECTS for c in CONDITIONS]
CUBE = 'visp_cube'


def visp_images():
    env = os.environ.get('VISP_INPUT_IMAGE_PATH')
    if env:
        return env if env.rstrip('/').endswith('ViSP-images') else os.path.join(env, 'ViSP-images')
    try:
        out = subprocess.run(['dpkg', '-L', 'visp-images-data'], capture_output=True, text=True).stdout.split()
    except OSError:
        return None
    return next((f for f in out if f.endswith('/ViSP-images')), None)


def is_sequence(d):
    return all(os.path.exists(os.path.join(d, f)) for f in ('frames', 'camera.yaml', 'model.cao', 'init_pose.txt',
                                                              'gt_poses.csv'))


def ensure_benchmark(args, names):
    missing = [s for s in names if not is_sequence(os.path.join(args.data, s))]
    if not missing:
        return
    present = [s for s in names if s not in missing]
    if present:
        # A folder that holds some of the sequences may come from another generator or other seeds
        # (a second instance): filling it up would overwrite those with the development split.
        sys.exit('compare_visp: %s holds %d of the selected sequences but not %s; not generating into it '
                 '(select what is there with --only, or give an empty --data folder)'
                 % (args.data, len(present), ', '.join(missing)))
    gen = os.path.join(args.shared_bench, 'make_sequences.py')
    if not os.path.exists(gen):
        sys.exit('compare_visp: %d sequences missing in %s and no generator at %s (--shared-bench)'
                 % (len(missing), args.data, gen))
    print('generating the benchmark into %s (%d sequences missing, ~6-10 min on 2 cores)' % (args.data, len(missing)),
          flush=True)
    subprocess.run(['/usr/bin/python3', gen, '--out', args.data, '--jobs', str(args.jobs)], check=True)


def ensure_visp_binary(args):
    src = os.path.join(REPO, 'bench', 'visp', 'visp_track.cpp')
    exe = args.visp_bin
    if os.path.exists(exe) and os.path.getmtime(exe) >= os.path.getmtime(src):
        return exe
    try:
        flags = subprocess.run(['pkg-config', '--cflags', '--libs', 'visp'], capture_output=True, text=True,
                               check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        sys.exit('compare_visp: pkg-config finds no ViSP: apt-get install -y libvisp-dev (or use --no-visp)')
    os.makedirs(os.path.dirname(exe), exist_ok=True)
    print('compiling %s' % exe, flush=True)
    subprocess.run(['g++', '-O2', '-Wall', '-Wextra', '-o', exe, src] + flags, check=True)
    return exe


def prepare_cube(args):
    """SEQ-like folder for ViSP's real cube; returns its path or None without visp-images-data."""
    root = visp_images()
    if not root or not os.path.isdir(os.path.join(root, 'mbt', 'cube')):
        print('note: visp-images-data is not installed: no real cube row (apt-get install -y visp-images-data)')
        return None
    d = os.path.join(args.data, CUBE)
    os.makedirs(d, exist_ok=True)
    shutil.copyfile(os.path.join(REPO, 'tests', 'data', 'visp_cube_camera.yaml'), os.path.join(d, 'camera.yaml'))
    with open(os.path.join(root, 'mbt', 'cube.0.pos')) as f:
        pose = f.read().split()
    with open(os.path.join(d, 'init_pose.txt'), 'w') as f:
        f.write(' '.join(pose[:6]) + '\n')
    return d


def seq_inputs(seq_dir, name):
    if name == CUBE:
        root = os.path.join(visp_images(), 'mbt')
        return dict(model=os.path.join(root, 'cube.cao'), frames=os.path.join(root, 'cube'),
                    gt=os.path.join(REPO, 'tests', 'data', 'visp_cube_reference.csv'))
    return dict(model=os.path.join(seq_dir, 'model.cao'), frames=os.path.join(seq_dir, 'frames'),
                gt=os.path.join(seq_dir, 'gt_poses.csv'))


def start_pose_file(seq_dir, k):
    """Start k of a sequence: 0 is its init_pose.txt; k > 0 the same moved by at most 0.1 mm per
    axis and 0.2 mrad per rotation-vector component (seeded by k): far below what a tracker can
    resolve, so that a sequence whose result changes with it is chaotic there, not better or worse."""
    base = os.path.join(seq_dir, 'init_pose.txt')
    if k == 0:
        return base
    with open(base) as f:
        v = [float(x) for x in f.read().split()[:6]]
    rng = random.Random(1000 + k)
    v = [x + rng.uniform(-1e-4, 1e-4) if i < 3 else x + rng.uniform(-2e-4, 2e-4) for i, x in enumerate(v)]
    path = os.path.join(seq_dir, 'init_pose_start%d.txt' % k)
    with open(path, 'w') as f:
        f.write(' '.join('%.9f' % x for x in v) + '\n')
    return path


def v4r_csv(args, seq_dir, k):
    stem = args.v4r_csv[:-4] if args.v4r_csv.endswith('.csv') else args.v4r_csv
    return os.path.join(seq_dir, args.v4r_csv if k == 0 else '%s_start%d.csv' % (stem, k))


def run_v4r(args, seq_dir, name, k=0):
    inp = seq_inputs(seq_dir, name)
    out = v4r_csv(args, seq_dir, k)
    cmd = [args.v4r, 'track', '--model', inp['model'], '--camera', os.path.join(seq_dir, 'camera.yaml'),
           '--input', inp['frames'], '--init-pose-file', start_pose_file(seq_dir, k), '--output', out]
    if args.config:
        cmd += ['--config', args.config]
    for s in args.set or []:
        cmd += ['--set', s]
    with open(os.path.join(seq_dir, 'v4r.log' if k == 0 else 'v4r_start%d.log' % k), 'w') as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    return rc == 0 and os.path.exists(out)


def run_visp(args, exe, seq_dir, name):
    inp = seq_inputs(seq_dir, name)
    out = os.path.join(seq_dir, 'visp.csv')
    if args.no_visp:
        return os.path.exists(out)
    if not args.rerun_visp and os.path.exists(out) and os.path.getmtime(out) >= os.path.getmtime(exe):
        return True
    cmd = [exe, '--model', inp['model'], '--camera', os.path.join(seq_dir, 'camera.yaml'), '--input', inp['frames'],
           '--init-pose-file', os.path.join(seq_dir, 'init_pose.txt'), '--output', out + '.tmp'] + (args.visp_arg or [])
    with open(os.path.join(seq_dir, 'visp.log'), 'w') as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    if rc != 0:
        return False
    os.replace(out + '.tmp', out)
    return True


def evaluate(args, gt, est):
    if not est or not os.path.exists(est):
        return None
    r = subprocess.run(['/usr/bin/python3', os.path.join(args.shared_bench, 'eval_poses.py'), gt, est, '--skip-first'],
                       capture_output=True, text=True)
    try:
        return json.loads(r.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        return None


def one(args, exe, name):
    seq_dir = os.path.join(args.data, name)
    ok_v4r = run_v4r(args, seq_dir, name)
    ok_visp = run_visp(args, exe, seq_dir, name) if exe or args.no_visp else False
    gt = seq_inputs(seq_dir, name)['gt']
    ev_v4r = evaluate(args, gt, v4r_csv(args, seq_dir, 0)) if ok_v4r else None
    ev_visp = evaluate(args, gt, os.path.join(seq_dir, 'visp.csv')) if ok_visp else None
    starts = [ev_v4r]
    for k in range(1, max(1, args.starts)):
        starts.append(evaluate(args, gt, v4r_csv(args, seq_dir, k)) if run_v4r(args, seq_dir, name, k) else None)
    return name, ev_v4r, ev_visp, [e['success_5cm5deg'] if e else 0.0 for e in starts]


def fmt_err(e):
    if not e or e.get('mean_t_mm') is None:
        return '%15s' % 'failed'
    return '%8.1f / %4.1f' % (e['mean_t_mm'], e['mean_r_deg'])


def fmt_pct(e):
    return '%6.1f' % (100 * e['success_5cm5deg']) if e else '%6s' % '-'


def fmt_ms(e):
    return '%6.2f' % e['median_ms'] if e and e.get('median_ms') is not None else '%6s' % '-'


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--shared-bench', default=os.path.join(os.path.dirname(REPO), 'shared', 'bench'),
                    help='folder of make_sequences.py and eval_poses.py (default: ../shared/bench)')
    ap.add_argument('--data', default='/tmp/v4r-bench', help='benchmark folder (generated if incomplete)')
    ap.add_argument('--v4r', default=os.path.join(REPO, 'build', 'bin', 'v4r'), help='v4r binary')
    ap.add_argument('--visp-bin', default=os.path.join(REPO, 'build', 'visp', 'visp_track'))
    ap.add_argument('--only', action='append', help='run sequences whose name contains this (repeatable)')
    ap.add_argument('--no-visp', action='store_true', help='do not run ViSP; use the cached SEQ/visp.csv')
    ap.add_argument('--rerun-visp', action='store_true', help='run ViSP even where SEQ/visp.csv is up to date')
    ap.add_argument('--no-cube', action='store_true', help='leave out ViSP\'s real cube')
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--config', help='v4r track --config FILE')
    ap.add_argument('--set', action='append', help='v4r track --set key=value (repeatable)')
    ap.add_argument('--visp-arg', action='append', help='extra argument for visp_track (repeatable)')
    ap.add_argument('--v4r-csv', default='v4r.csv', help='name of v4r\'s pose CSV in each sequence folder')
    ap.add_argument('--starts', type=int, default=1,
                    help='run v4r from this many starts: the given one and others moved by at most 0.1 mm / 0.2 mrad; '
                         'a column gives the success over them (mean, min-max): which sequences are chaotic')
    ap.add_argument('--json', help='also write all numbers to this JSON file')
    args = ap.parse_args()

    if not os.path.exists(args.v4r):
        sys.exit('compare_visp: no v4r binary at %s (build first, or --v4r)' % args.v4r)
    names = [s for s in SEQUENCES if not args.only or any(o in s for o in args.only)]
    ensure_benchmark(args, names)
    exe = None if args.no_visp else ensure_visp_binary(args)
    if not args.no_cube and (not args.only or any(o in CUBE for o in args.only)) and prepare_cube(args):
        names.append(CUBE)
    if not names:
        sys.exit('compare_visp: no sequence matches --only %s' % args.only)

    results = {}
    with cf.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for name, ev, evv, succ in pool.map(lambda n: one(args, exe, n), names):
            results[name] = (ev, evv, succ)
            print('done %s' % name, file=sys.stderr, flush=True)

    many = args.starts > 1
    starts_col = lambda succ: ('  %5.1f [%5.1f-%5.1f]' % (100 * sum(succ) / len(succ), 100 * min(succ), 100 * max(succ))
                               if many else '')
    print('%-18s %6s %6s  %15s  %15s  %6s %6s%s' % ('sequence', 'v4r%', 'ViSP%', 'v4r mm / deg', 'ViSP mm / deg',
                                                    'v4r ms', 'ViSPms',
                                                    '  v4r%% over %d starts' % args.starts if many else ''))
    sums = {'v4r': [], 'visp': [], 'starts': []}
    for name in names:
        ev, evv, succ = results[name]
        if name == CUBE:
            print('%-18s %6s %6s  %15s  %15s  %6s %6s%s' % (name, fmt_pct(ev).strip(), 'ref', fmt_err(ev), 'ref',
                                                            fmt_ms(ev), fmt_ms(evv), starts_col(succ)))
            continue
        print('%-18s %6s %6s  %15s  %15s  %6s %6s%s' % (name, fmt_pct(ev), fmt_pct(evv), fmt_err(ev), fmt_err(evv),
                                                        fmt_ms(ev), fmt_ms(evv), starts_col(succ)))
        sums['v4r'].append(ev['success_5cm5deg'] if ev else 0.0)
        sums['visp'].append(evv['success_5cm5deg'] if evv else 0.0)
        sums['starts'].append(sum(succ) / len(succ))
    if sums['v4r']:
        n = len(sums['v4r'])
        print('%-18s %6.1f %6.1f   (mean success over %d sequences; success = t < 5 cm and R < 5 deg, frames 1..)%s'
              % ('mean', 100 * sum(sums['v4r']) / n, 100 * sum(sums['visp']) / n, n,
                 '; over %d starts: %.1f' % (args.starts, 100 * sum(sums['starts']) / n) if many else ''))
    print('mm / deg: mean translation / rotation error; ms: median cycle (v4r: tracking without decoding; '
          'ViSP: track() call)')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({k: {'v4r': v[0], 'visp': v[1], 'v4r_success_per_start': v[2]} for k, v in results.items()}, f,
                      indent=1)


if __name__ == '__main__':
    main()
