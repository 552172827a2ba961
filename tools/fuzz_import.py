#!/usr/bin/env python3
"""Damages real assets at random and imports them with costume-catalog, to find files that
crash, hang or exhaust the importer instead of being refused with a message.

Each case copies one seed (a file of ../shared/data, or the built-in garment scene) into a
fresh folder, damages it (truncation, flipped bytes, a deleted or repeated chunk, numbers
replaced by extremes such as 1e308, nan or 2147483648, lines deleted, repeated or replaced)
and runs `costume-catalog import` on it into a throw-away SQLite catalogue, thumbnails on.
A case is bad when the program neither stores the file (exit 0) nor refuses it with an error
(exit 1 and "error" in its output): a signal, another exit status or a hang beyond
--timeout. Bad cases are kept under --keep with the output's end.

    python3 tools/fuzz_import.py --count 300 --seed 1

With --stored, the seeds are imported once, undamaged, and each case damages a copy of that
SQLite catalogue (flipped bytes, runs of 0x00 or 0xff) and runs `costume-catalog check` on
it, which loads every stored entry as the simulation server and the GUI do: a bad case is a
signal, another exit status than 0 or 1, or a hang. Entries whose loading crashed the check's
child are counted apart ("crashed, reported"): each is a crash that a program loading the
entry outside a child would suffer.

Prints one line per case and a summary; exits 1 when any case was bad. Not a test: it
needs ../shared/data and takes minutes (docs/catalog.md, "Safety").
"""
import argparse
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

# (kind, files of one import with their sources, how each reaches the program: None as a
# file argument, an option naming it, or 'beside' when it is found beside the first file)
SUIT = 'makehuman/clothes/female_casualsuit02/female_casualsuit02'
SEEDS = [
    ('avatar', ['khronos-cesiumman/CesiumMan.glb'], [None]),
    ('animation', ['khronos-cesiumman/CesiumMan.glb'], [None]),
    ('animation', ['cmu-mocap-bvh/10_01.bvh'], [None]),
    ('animation', ['makehuman/bvh/walk1_mhskel.bvh'], [None]),
    ('animation', ['deepmimic-motions/motions/humanoid3d_kick.txt',
                   'deepmimic-motions/characters/humanoid3d.txt'], [None, '--character']),
    ('avatar', ['makehuman/body/base.obj', 'makehuman/body/default.mhskel',
                'makehuman/body/default_weights.mhw'], [None, None, None]),
    ('garment', ['@scenes/garment.toml'], [None]),
    ('garment', [SUIT + '.mhclo', SUIT + '.obj', 'makehuman/body/base.obj',
                 'makehuman/body/default.mhskel', 'makehuman/body/default_weights.mhw'],
     [None, 'beside', '--makehuman-body', '--makehuman-skeleton', '--makehuman-weights']),
]
NUMBER = re.compile(rb'-?\d+(\.\d+)?([eE][-+]?\d+)?')
EXTREMES = [b'1e308', b'-1e308', b'nan', b'inf', b'-1', b'0', b'999999999', b'-999999999',
            b'1e-320', b'2147483648', b'']


def damage(data, rng):
    """Returns the damaged bytes and what was done to them."""
    data = bytearray(data)
    text = b'\0' not in data[:4096]  # UTF-8 text too (scene files write m/s²)
    how = rng.choice(['truncate', 'flip', 'chunk'] + (['numbers', 'lines'] * 2 if text else []))
    if how == 'truncate':
        return bytes(data[:rng.randrange(len(data))]), how
    if how == 'flip':
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return bytes(data), how
    if how == 'chunk':
        i = rng.randrange(len(data))
        j = min(len(data), i + rng.randint(1, 4096))
        if rng.random() < 0.5:
            return bytes(data[:i] + data[j:]), 'chunk deleted'
        k = rng.randrange(len(data))
        return bytes(data[:k] + data[i:j] + data[k:]), 'chunk repeated'
    if how == 'numbers':
        used = []
        for _ in range(rng.randint(1, 5)):
            matches = list(NUMBER.finditer(data))
            if not matches:
                break
            m = rng.choice(matches)
            value = rng.choice(EXTREMES)
            used.append(value.decode() or 'nothing')
            data = data[:m.start()] + value + data[m.end():]
        return bytes(data), 'numbers: ' + ', '.join(used)
    lines = bytes(data).split(b'\n')
    i = rng.randrange(len(lines))
    r = rng.random()
    if r < 0.4:
        del lines[i]
    elif r < 0.7:
        lines.insert(i, lines[rng.randrange(len(lines))])
    else:
        lines[i] = bytes(rng.randrange(32, 127) for _ in range(rng.randint(0, 40)))
    return b'\n'.join(lines), 'lines'


def run_program(command, timeout):
    """The program's exit status ('timeout' after `timeout` s) and its output, both streams."""
    try:
        done = subprocess.run(command, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return 'timeout', ''
    return done.returncode, (done.stdout + done.stderr).decode(errors='replace')


def source_path(name, data_folder):
    return os.path.join(REPO, name[1:]) if name.startswith('@') else os.path.join(data_folder, name)


def run_case(n, rng, args, work, catalogue):
    kind, files, roles = rng.choice([seed for seed in SEEDS if args.only in seed[1][0]])
    victim = rng.randrange(len(files))
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    paths, how = [], ''
    for k, name in enumerate(files):
        with open(source_path(name, args.data), 'rb') as f:
            data = f.read()
        if k == victim:
            data, how = damage(data, rng)
        path = os.path.join(work, os.path.basename(name))
        with open(path, 'wb') as f:
            f.write(data)
        paths.append(path)
    command = [args.program, '--url', 'sqlite:' + catalogue, 'import', '--kind', kind,
               '--root', work, '--name', 'case%d' % n]
    for path, role in zip(paths, roles):
        command += [path] if role is None else [] if role == 'beside' else [role, path]
    status, output = run_program(command, args.timeout)
    what = '%s %s (%s)' % (kind, os.path.basename(files[victim]), how)
    bad = status not in (0, 1) or (status == 1 and 'error' not in output)
    if bad:
        keep = os.path.join(args.keep, 'case%d' % n)
        shutil.copytree(work, keep)
        print('BAD %s: %s, kept in %s; %s' % (what, status, keep, output[-300:]), flush=True)
    else:
        said = [line.strip() for line in output.splitlines() if line.startswith('  ')]
        print('%s %s%s' % ('stored' if status == 0 else 'refused', what,
                           ': ' + said[0][:200] if said else ''), flush=True)
    return bad


def import_seeds(args, catalogue, scratch):
    """Imports every seed, undamaged, into `catalogue` (no thumbnails)."""
    for n, (kind, files, roles) in enumerate(SEEDS):
        command = [args.program, '--url', 'sqlite:' + catalogue, '--no-thumbnails', 'import',
                   '--kind', kind, '--root', scratch, '--name', 'seed%d' % n]
        folder = os.path.join(scratch, 'seed%d' % n)
        os.makedirs(folder)
        for name, role in zip(files, roles):
            path = os.path.join(folder, os.path.basename(name))
            shutil.copy(source_path(name, args.data), path)
            command += [path] if role is None else [] if role == 'beside' else [role, path]
        subprocess.run(command, check=True, capture_output=True, timeout=args.timeout)


def damage_stored(data, rng):
    """Flips bytes or writes runs of 0x00 / 0xff at random places, keeping the file's size."""
    data = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        i = rng.randrange(len(data))
        for k in range(i, min(len(data), i + rng.choice([1, 1, 4, 16]))):
            data[k] = rng.choice([0, 0xff, rng.randrange(256)])
    return bytes(data)


def run_stored_case(n, rng, args, base, catalogue):
    """Returns (bad, crashed entries reported)."""
    with open(base, 'rb') as f:
        data = damage_stored(f.read(), rng)
    with open(catalogue, 'wb') as f:
        f.write(data)
    command = [args.program, '--url', 'sqlite:' + catalogue, '--no-thumbnails', 'check']
    status, output = run_program(command, args.timeout)
    crashed = output.count('crashed (signal')
    if status not in (0, 1):
        keep = os.path.join(args.keep, 'stored%d.sqlite' % n)
        os.makedirs(args.keep, exist_ok=True)
        shutil.copy(catalogue, keep)
        print('BAD check: %s, kept in %s; %s' % (status, keep, output[-300:]), flush=True)
        return True, crashed
    problems = [line for line in output.splitlines() if line.startswith('  ')]
    print('%s%s' % ('sound' if status == 0 else '%d problem(s)' % len(problems),
                    ': ' + problems[0].strip()[:200] if problems else ''), flush=True)
    return False, crashed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--count', type=int, default=100, help='cases to run (default 100)')
    parser.add_argument('--seed', type=int, default=1, help='random seed (default 1)')
    parser.add_argument('--data', default=os.path.join(REPO, '..', 'shared', 'data'),
                        help='the shared assets folder (default ../shared/data)')
    parser.add_argument('--program', default=os.path.join(REPO, 'build', 'catalog',
                                                          'costume-catalog'),
                        help='the costume-catalog program (default build/catalog/...)')
    parser.add_argument('--timeout', type=float, default=120.0,
                        help='seconds a case may take before it counts as a hang (default 120)')
    parser.add_argument('--only', default='',
                        help='damage only the seeds whose first file path contains this '
                             '(e.g. mhclo; default: all)')
    parser.add_argument('--stored', action='store_true',
                        help='damage a catalogue holding the seeds and check it, instead of '
                             'damaging files to import')
    parser.add_argument('--keep', default=os.path.join(tempfile.gettempdir(), 'fuzz_import'),
                        help='folder for the bad cases (default /tmp/fuzz_import)')
    args = parser.parse_args()
    if not any(args.only in files[0] for _, files, _ in SEEDS):
        sys.exit('fuzz_import: no seed file matches --only %s' % args.only)
    for _, files, _ in SEEDS:
        for name in files:
            if not os.path.isfile(source_path(name, args.data)):
                sys.exit('fuzz_import: %s is missing (--data)' % source_path(name, args.data))
    if not os.access(args.program, os.X_OK):
        sys.exit('fuzz_import: %s is not a program (build first, or --program)' % args.program)
    rng = random.Random(args.seed)
    start = time.time()
    with tempfile.TemporaryDirectory(prefix='fuzz_import-') as scratch:
        work, catalogue = os.path.join(scratch, 'in'), os.path.join(scratch, 'catalog.sqlite')
        if not args.stored:
            bad = sum(run_case(n, rng, args, work, catalogue) for n in range(args.count))
            print('%d cases, %d bad, in %.0f s' % (args.count, bad, time.time() - start))
            return 1 if bad else 0
        base = os.path.join(scratch, 'seeds.sqlite')
        import_seeds(args, base, scratch)
        results = [run_stored_case(n, rng, args, base, catalogue) for n in range(args.count)]
    bad = sum(b for b, _ in results)
    crashed = sum(c for _, c in results)
    print('%d cases, %d bad, %d entries crashed, reported, in %.0f s'
          % (args.count, bad, crashed, time.time() - start))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
