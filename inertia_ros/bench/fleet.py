"""Fleet benchmark: a simulated fleet of logs, ``fleet`` throughput against worker count.

``python -m inertia_ros.bench.fleet --fleet-dir /tmp/fleet200 --out docs`` builds (once; it is
reused while its manifest matches) a fleet of ``--vehicles`` x ``--logs-per-vehicle`` logs of
``--duration`` seconds from the nominal scene, plus ``--corrupt`` unusable logs, with a
payload released on one vehicle, then times:

- ``python -m inertia_ros fleet DIR --out T.parquet --workers N`` as a whole process, for each
  N of ``--workers`` (fresh table each time): logs/s and the speed-up over one worker;
- the same command again on the finished table (the incremental re-run: adds nothing);
- ``python -m inertia_ros estimate LOG --format json`` as a whole process on a few logs
  (the single-log CLI), against the in-fleet time per log (the rows' ``wall_s``);
- the report (``--report``): outliers found, and whether the payload change is among them.

Results go to ``OUT/fleet_bench.json`` and a Markdown section printed on stdout; ``--doc
docs/BENCHMARKS.md`` also puts it into that file between its own markers (the rest of the file
belongs to ``python -m inertia_ros bench``).

The fleet
---------
Vehicle ``sat-NN`` (NN = 01 ...) has its own tensor (the nominal one with each principal
moment scaled by a seeded factor in [0.85, 1.15], products kept) and flies one log a day
from 2026-01-01 (``--logs-per-vehicle`` days), each log from its own seed.  The last vehicle
writes rosbag2 directories instead of single files.  On the payload vehicle (the first one)
the log of day ``logs_per_vehicle // 2`` is the ``payload_change`` scene (the payload is
released half way through it) and later logs fly the lighter tensor, so its trend steps down
once and the report must flag the log after the change.  The corrupt logs sit beside the
good ones of the second vehicle: an empty file, random bytes, the first KiB of a real log
(no messages), and a rosbag2 directory whose metadata.yaml is not YAML.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['FleetSpec', 'make_fleet', 'run_fleet_bench']

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / 'config' / 'scenes'
#: 2026-01-01T00:00:00Z [ns]: the first log day.
DAY0_NS = 1_767_225_600 * 10 ** 9
DAY_NS = 86_400 * 10 ** 9


@dataclass(frozen=True)
class FleetSpec:
    """What :func:`make_fleet` builds.

    Attributes
    ----------
    vehicles : int
        Number of vehicles (>= 2).
    logs_per_vehicle : int
        Good logs per vehicle, one a day (>= 2).
    duration : float
        Length of each log [s].
    corrupt : int
        Unusable logs added to the second vehicle's directory (0-4).
    seed : int
        Master seed (vehicle tensors and log seeds derive from it).
    """

    vehicles: int = 14
    logs_per_vehicle: int = 14
    duration: float = 600.0
    corrupt: int = 4
    seed: int = 2026

    @property
    def total(self) -> int:
        """Number of logs in the fleet, good and corrupt."""
        return self.vehicles * self.logs_per_vehicle + self.corrupt


def _scene_dict(name: str) -> dict[str, Any]:
    from inertia_ros.io.scene_file import load_scene_dict

    return load_scene_dict(SCENES / f'{name}.yaml')


def _vehicle_tensor(rng: np.random.Generator) -> list[float]:
    base = np.array([1.0, 1.2, 0.9, 0.05, -0.03, 0.02])
    scale = rng.uniform(0.85, 1.15, size=3)
    return [*(base[:3] * scale).tolist(), *base[3:].tolist()]


def _jobs(spec: FleetSpec, root: Path) -> list[dict[str, Any]]:
    """One job per good log: where, which scene dict, seed, start time, format."""
    rng = np.random.default_rng(spec.seed)
    payload = _scene_dict('payload_change')
    jobs = []
    for v in range(spec.vehicles):
        name = f'sat-{v + 1:02d}'
        tensor = _vehicle_tensor(rng)
        bag_dir = v == spec.vehicles - 1 and spec.vehicles > 2
        for day in range(spec.logs_per_vehicle):
            if v == 0:  # the payload vehicle
                mid = spec.logs_per_vehicle // 2
                scene = dict(payload)
                scene['duration'] = spec.duration
                if day < mid:
                    scene.pop('inertia_change')
                elif day == mid:
                    scene['inertia_change'] = dict(payload['inertia_change'],
                                                   time=spec.duration / 2)
                else:
                    scene['body'] = {'inertia': list(payload['inertia_change']['inertia'])}
                    scene.pop('inertia_change')
            else:
                scene = _scene_dict('default')
                scene['duration'] = spec.duration
                scene['body'] = {'inertia': tensor}
            stamp = DAY0_NS + day * DAY_NS + v * 600 * 10 ** 9
            out = root / name / f'{name}_day{day + 1:03d}{"" if bag_dir else ".mcap"}'
            jobs.append({'out': str(out), 'scene': scene, 'vehicle': name,
                         'seed': int(rng.integers(2 ** 31)), 'start_ns': stamp,
                         'bag_dir': bag_dir})
    return jobs


def _write_one(job: dict[str, Any]) -> str:
    from inertia_ros.core.scene import Scene
    from inertia_ros.core.simulation import simulate
    from inertia_ros.io.mcap_writer import write_simulation

    result = simulate(Scene.from_dict(job['scene']), seed=job['seed'])
    out = Path(job['out'])
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        shutil.rmtree(out) if out.is_dir() else out.unlink()
    write_simulation(out, result, start_ns=job['start_ns'], rosbag2_dir=job['bag_dir'],
                     extra_metadata={'vehicle': job['vehicle']})
    return str(out)


def _write_corrupt(spec: FleetSpec, root: Path, sample: Path) -> list[str]:
    d = root / 'sat-02'
    d.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(spec.seed + 1)
    made = []
    kinds = ['empty', 'random', 'no_messages', 'bad_bag'][:spec.corrupt]
    for kind in kinds:
        if kind == 'empty':
            p = d / 'sat-02_corrupt_empty.mcap'
            p.write_bytes(b'')
        elif kind == 'random':
            p = d / 'sat-02_corrupt_random.mcap'
            p.write_bytes(rng.bytes(50_000))
        elif kind == 'no_messages':
            p = d / 'sat-02_corrupt_no_messages.mcap'
            p.write_bytes(sample.read_bytes()[:1024])
        else:
            p = d / 'sat-02_corrupt_bag'
            p.mkdir(exist_ok=True)
            (p / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed\n')
            (p / 'sat-02_corrupt_bag_0.mcap').write_bytes(sample.read_bytes()[:4096])
        made.append(str(p))
    return made


def make_fleet(root: str | os.PathLike[str], spec: FleetSpec, processes: int = 1
               ) -> dict[str, Any]:
    """Write the fleet under ``root`` (one directory per vehicle); reuse a matching one.

    Parameters
    ----------
    root : str or PathLike
        Fleet directory; ``root/manifest.json`` records the spec it was built from.
    spec : FleetSpec
    processes : int, optional
        Simulate in this many processes.

    Returns
    -------
    dict
        The manifest: ``spec``, ``logs`` (good log paths), ``corrupt`` (paths),
        ``payload`` (``vehicle``, ``change_log``: the log with the in-log change, ``first_after``:
        the first log after it), ``seconds`` (time to build).
    """
    root = Path(root)
    manifest_path = root / 'manifest.json'
    if manifest_path.is_file():
        try:
            manifest = json.loads(manifest_path.read_text())
            if manifest.get('spec') == asdict(spec) and all(
                    Path(p).exists() for p in manifest['logs'] + manifest['corrupt']):
                return manifest
        except (ValueError, KeyError):
            pass
    if root.exists():
        shutil.rmtree(root)
    root.mkdir(parents=True)
    t0 = time.perf_counter()
    jobs = _jobs(spec, root)
    if processes > 1:
        with ProcessPoolExecutor(processes) as pool:
            logs = list(pool.map(_write_one, jobs, chunksize=4))
    else:
        logs = [_write_one(j) for j in jobs]
    corrupt = _write_corrupt(spec, root, Path(logs[0]))
    mid = spec.logs_per_vehicle // 2
    manifest = {
        'spec': asdict(spec), 'logs': logs, 'corrupt': corrupt,
        'payload': {'vehicle': 'sat-01', 'change_log': logs[mid],
                    'first_after': logs[mid + 1] if mid + 1 < spec.logs_per_vehicle else None},
        'seconds': time.perf_counter() - t0}
    manifest_path.write_text(json.dumps(manifest, indent=1))
    return manifest


# --------------------------------------------------------------------------------------------
# Timing


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _run(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, str, float]:
    """Run ``cmd``; return its wall time [s], stdout and CPU time [s] (itself + children)."""
    t0, c0 = time.perf_counter(), _children_cpu()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f'{" ".join(cmd)}: exit {proc.returncode}: {proc.stderr[-2000:]}')
    return dt, proc.stdout, _children_cpu() - c0


def run_fleet_bench(fleet_dir: Path, out_dir: Path, spec: FleetSpec, workers: list[int],
                    single: int = 5, build_processes: int = 2) -> dict[str, Any]:
    """Build (or reuse) the fleet and time the ``fleet`` command; return the results."""
    from inertia_ros.fleet.report import find_outliers
    from inertia_ros.fleet.table import read_rows

    py = sys.executable
    manifest = make_fleet(fleet_dir, spec, processes=build_processes)
    out_dir.mkdir(parents=True, exist_ok=True)
    work = fleet_dir.parent / (fleet_dir.name + '_results')
    work.mkdir(exist_ok=True)
    res: dict[str, Any] = {'spec': asdict(spec), 'logs': spec.total, 'cpu_count': os.cpu_count(),
                           'loadavg_before': os.getloadavg(),
                           'build_seconds': manifest['seconds'], 'runs': []}
    table = None
    for n in workers:
        table = work / f'fleet_w{n}.parquet'
        table.unlink(missing_ok=True)
        load = os.getloadavg()[0]
        dt, summary, cpu = _run([py, '-m', 'inertia_ros', 'fleet', str(fleet_dir), '--out',
                                 str(table), '--workers', str(n), '--no-progress'])
        rows = read_rows(table)
        res['runs'].append({'workers': n, 'seconds': dt, 'logs_per_s': len(rows) / dt,
                            'rows': len(rows), 'cpu_s': cpu, 'loadavg_1min_before': load,
                            'errors': sum(r['status'] == 'error' for r in rows),
                            'median_task_wall_s': statistics.median(r['wall_s'] for r in rows),
                            'median_task_cpu_s': statistics.median(r['cpu_s'] for r in rows),
                            'summary': summary.strip()})
        print(f'{n} workers: {dt:.1f} s, {len(rows) / dt:.2f} logs/s', file=sys.stderr)
    ones = [r['seconds'] for r in res['runs'] if r['workers'] == 1]
    for r in res['runs']:
        r['speedup'] = statistics.mean(ones) / r['seconds'] if ones else None
        r['cores_used'] = r['cpu_s'] / r['seconds']
    assert table is not None
    # the incremental re-run (nothing new), then the report on the finished table
    dt, summary, cpu = _run([py, '-m', 'inertia_ros', 'fleet', str(fleet_dir), '--out',
                             str(table), '--no-progress'])
    res['rerun'] = {'seconds': dt, 'summary': summary.strip(),
                    'fraction_of_first': dt / res['runs'][-1]['seconds']}
    report_dir = out_dir / 'fleet_report'
    dt, _, _ = _run([py, '-m', 'inertia_ros', 'fleet', str(fleet_dir), '--out', str(table),
                     '--no-progress', '--report', str(report_dir)])
    res['report_seconds'] = dt
    rows = read_rows(table)
    outliers = find_outliers(rows)
    res['outliers'] = [{k: o[k] for k in ('vehicle', 'path', 'sigma', 'worst')}
                       for o in outliers]
    flagged = {o['path'] for o in outliers}
    payload = manifest['payload']
    res['payload_flagged'] = bool({payload['change_log'], payload['first_after']} & flagged)
    res['false_outliers'] = sum(o['path'] not in (payload['change_log'],
                                                  payload['first_after']) for o in outliers)
    res['comparisons'] = sum(max(0, sum(r['vehicle'] == v and r['status'] == 'ok'
                                        for r in rows) - 1)
                             for v in {r['vehicle'] for r in rows})
    res['statuses'] = dict(sorted({s: sum(r['status'] == s for r in rows)
                                   for s in {r['status'] for r in rows}}.items()))
    # the single-log CLI, whole process, on a few good logs
    samples = manifest['logs'][1:1 + single]
    cli_wall, cli_cpu = [], []
    for p in samples:
        dt, _, cpu = _run([py, '-m', 'inertia_ros', 'estimate', p, '--format', 'json',
                           '--no-progress', '-o', str(work / 'single.json')])
        cli_wall.append(dt)
        cli_cpu.append(cpu)
    res['single_cli'] = {'median_wall_s': statistics.median(cli_wall),
                         'median_cpu_s': statistics.median(cli_cpu), 'wall_s': cli_wall,
                         'cpu_s': cli_cpu}
    res['loadavg_after'] = os.getloadavg()
    (out_dir / 'fleet_bench.json').write_text(json.dumps(res, indent=1))
    return res


def markdown(res: dict[str, Any], command: str) -> str:
    """The docs/BENCHMARKS.md section for a result of :func:`run_fleet_bench`."""
    s = res['spec']
    lines = [f'{res["logs"]} logs ({s["vehicles"]} vehicles x {s["logs_per_vehicle"]} '
             f'logs of {s["duration"]:g} s at 200 Hz gyro + 50 Hz torque, plus {s["corrupt"]} '
             f'corrupt ones), on {res["cpu_count"]} cores shared with other jobs: "cores used" is '
             f'how much CPU the run got; a speed-up needs the second core to be free.', '',
             '| workers | wall time [s] | logs/s | speed-up over 1 worker (mean) | CPU [s] | '
             'cores used (CPU / wall) | load before | rows | errors |',
             '| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
    for r in res['runs']:
        sp = '' if r['speedup'] is None else f'{r["speedup"]:.2f}x'
        lines.append(f'| {r["workers"]} | {r["seconds"]:.1f} | {r["logs_per_s"]:.2f} | {sp} '
                     f'| {r["cpu_s"]:.0f} | {r["cores_used"]:.2f} | '
                     f'{r["loadavg_1min_before"]:.1f} | {r["rows"]} | {r["errors"]} |')
    rr, cli, last = res['rerun'], res['single_cli'], res['runs'][-1]
    lines += ['', f'- Re-run on the finished table (nothing new): {rr["seconds"]:.1f} s = '
              f'{100 * rr["fraction_of_first"]:.1f} % of the run before it; `--report` on '
              f'the finished table: {res["report_seconds"]:.1f} s.',
              f'- Per log: {last["median_task_cpu_s"]:.2f} CPU s inside a fleet worker '
              f'(median; wall {last["median_task_wall_s"]:.2f} s with {last["workers"]} '
              f'workers sharing the cores) against {cli["median_cpu_s"]:.2f} CPU s '
              f'({cli["median_wall_s"]:.2f} s wall) for `python -m inertia_ros estimate LOG '
              f'--format json` as a whole process (median of {len(cli["wall_s"])}): a worker '
              f'pays the interpreter and the imports once, not per log.',
              '- Statuses: ' + ', '.join(f'{n} {k}' for k, n in res['statuses'].items()) + '.',
              f'- Outliers flagged: {len(res["outliers"])}; the payload change on sat-01 '
              f'{"is" if res["payload_flagged"] else "is NOT"} among them; '
              f'{res["false_outliers"]} other (false) alarms in {res["comparisons"]} '
              f'log-to-log comparisons (expected at the 3-sigma rate: '
              f'{0.0027 * res["comparisons"]:.1f}).',
              '', f'Command: `{command}`']
    return '\n'.join(lines) + '\n'


BEGIN = '<!-- fleet-bench: written by python -m inertia_ros.bench.fleet --doc; do not edit -->'
END = '<!-- /fleet-bench -->'
HEADING = '## Fleet: many logs on Dask'


def update_doc(doc: Path, section: str) -> None:
    """Put ``section`` into ``doc`` between the fleet markers (appended the first time)."""
    text = doc.read_text(encoding='utf-8') if doc.exists() else ''
    block = f'{BEGIN}\n{HEADING}\n\n{section.rstrip()}\n{END}\n'
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + block + rest.split(END, 1)[1].lstrip('\n')
    else:
        text = text.rstrip('\n') + '\n\n' + block
    doc.write_text(text, encoding='utf-8')


def main(argv: list[str] | None = None) -> int:
    """Command line of the fleet benchmark."""
    p = argparse.ArgumentParser(prog='python -m inertia_ros.bench.fleet',
                                description=__doc__.split('\n\n')[0])
    p.add_argument('--fleet-dir', type=Path, default=Path('/tmp/inertia_fleet'),
                   help='where the simulated fleet is built (reused while it matches)')
    p.add_argument('--out', type=Path, default=Path('docs'),
                   help='fleet_bench.json and fleet_report/ go here')
    p.add_argument('--vehicles', type=int, default=FleetSpec.vehicles)
    p.add_argument('--logs-per-vehicle', type=int, default=FleetSpec.logs_per_vehicle)
    p.add_argument('--duration', type=float, default=FleetSpec.duration, help='[s] per log')
    p.add_argument('--corrupt', type=int, default=FleetSpec.corrupt, choices=range(5))
    p.add_argument('--workers', default='1,2', help='comma-separated worker counts')
    p.add_argument('--single', type=int, default=5, help='single-log CLI runs to time')
    p.add_argument('--build-processes', type=int, default=2)
    p.add_argument('--doc', type=Path, default=None, metavar='FILE.md',
                   help='also write the section into FILE.md (e.g. docs/BENCHMARKS.md), '
                        'between its markers, appended the first time')
    args = p.parse_args(argv)
    if args.vehicles < 2 or args.logs_per_vehicle < 2:
        p.error('--vehicles and --logs-per-vehicle must be >= 2')
    spec = FleetSpec(args.vehicles, args.logs_per_vehicle, args.duration, args.corrupt)
    workers = [int(x) for x in args.workers.split(',') if x.strip()]
    res = run_fleet_bench(args.fleet_dir, args.out, spec, workers, args.single,
                          args.build_processes)
    cmd = ('python -m inertia_ros.bench.fleet ' + ' '.join(argv if argv is not None
                                                           else sys.argv[1:])).strip()
    section = markdown(res, cmd)
    if args.doc is not None:
        update_doc(args.doc, section)
    sys.stdout.write(section)
    return 0


if __name__ == '__main__':
    sys.exit(main())
