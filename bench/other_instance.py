#!/usr/bin/python3
"""Another instance of the shared benchmark: the same generator, conditions and parameters, other
object seeds (trajectory, texture, background, noise), so that a change to the tracker can be
judged on frames it was not tuned on.

    /usr/bin/python3 bench/other_instance.py --seeds 1111,2222,3333 --out /tmp/v4r-bench2 \\
        --conditions regular occlusion blur fast
    /usr/bin/python3 bench/compare_visp.py --no-visp --no-cube --data /tmp/v4r-bench2 \\
        --only _regular --only _occlusion --only _blur --only _fast

The shared generator (--shared-bench, default ../shared/bench next to the repository) is not
changed: it is read, its development seeds (OBJECT_SEEDS, one per object: box, mockup, flange)
are replaced in a copy in the output folder, and the copy is run there. Other arguments
(--conditions, --objects, --jobs, ...) are passed to it. The seeds are written to
DIR/instance_seeds.txt. The development split's seeds are refused: that instance exists already.
"""
import argparse
import os
import re
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OBJECTS = ('box', 'mockup', 'flange')
SEEDS_LINE = re.compile(r'^OBJECT_SEEDS\s*=\s*\{([^}]*)\}', re.MULTILINE)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', required=True, help='three integers, the seeds of box, mockup and flange')
    ap.add_argument('--out', required=True, help='folder of the new instance')
    ap.add_argument('--shared-bench', default=os.path.join(os.path.dirname(REPO), 'shared', 'bench'))
    args, rest = ap.parse_known_args()
    try:
        seeds = [int(s) for s in args.seeds.split(',')]
    except ValueError:
        sys.exit('other_instance: --seeds %r: three integers separated by commas' % args.seeds)
    if len(seeds) != len(OBJECTS):
        sys.exit('other_instance: --seeds %r: one seed per object (%s)' % (args.seeds, ', '.join(OBJECTS)))
    gen = os.path.join(args.shared_bench, 'make_sequences.py')
    try:
        with open(gen) as f:
            src = f.read()
    except OSError as e:
        sys.exit('other_instance: cannot read the generator: %s (--shared-bench)' % e)
    m = SEEDS_LINE.search(src)
    if not m:
        sys.exit('other_instance: %s has no OBJECT_SEEDS = {...} line: the generator changed' % gen)
    dev = [int(v) for v in re.findall(r"'\w+'\s*:\s*(\d+)", m.group(1))]
    if seeds == dev:
        sys.exit('other_instance: %s are the development seeds; that instance is made by %s itself' % (args.seeds, gen))
    new = 'OBJECT_SEEDS = {%s}' % ', '.join("'%s': %d" % (o, s) for o, s in zip(OBJECTS, seeds))
    os.makedirs(args.out, exist_ok=True)
    copy = os.path.join(args.out, 'make_sequences_instance.py')
    with open(copy, 'w') as f:
        f.write(src[:m.start()] + new + src[m.end():])
    with open(os.path.join(args.out, 'instance_seeds.txt'), 'w') as f:
        f.write('%s\n' % new)
    sys.exit(subprocess.run(['/usr/bin/python3', copy, '--out', args.out] + rest).returncode)


if __name__ == '__main__':
    main()
