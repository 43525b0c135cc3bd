"""MRPT's rbpf-slam, icp-slam and pf-localization (Debian's mrpt-apps) on the same real scans and
odometry as ours.

For benchmarks/bench_slam_real: the peers get a log's scans with the odometry our SLAM and AMCL
get, and give back one pose per scan, their CPU time and peak memory, so every mapper is scored
the same way in the same run (testkit.real_data.score), and every localiser too
(testkit.real_data.judge_localization).

How:
- Debian's carmen2rawlog (2.5.8) is not used: it writes wrong timestamps and a rawlog of bare
  observations that rbpf-slam cannot read. Our own converter (mrpt/scans_to_mrpt.cpp, compiled
  on first use into build/mrpt-converter/ against libmrpt-obs-dev) writes the "actions and
  observations" rawlog: per scan a CActionRobotMovement2D with the odometry increment and a
  CSensoryFrame with the CObservation2DRangeScan. For pf-localization it also writes the map, as a
  simplemap: the scans the map is drawn from, at their reference poses; pf-localization builds its
  own grid from it (mrpt/pf-localization.ini), as our AMCL's map is drawn from the same scans.
- The motion model of each increment carries GMapping's odometry noise (srr 0.1, srt 0.2,
  str 0.1, stt 0.2) in MRPT's Gaussian model (std linear in distance and turn, as Thrun's): MRPT
  recomputes the distribution when it reads a rawlog, and its Thrun model is a set of random
  samples whose mean, the odometry the apps use, then errs at random (icp-slam unseeded: runs
  on aces differed from 0.48 to 2.7 m). With MRPT's default noise rbpf-slam diverges on real
  data (issue #21); pfOptimalProposal itself uses only the mean, as the start of its scan match.
- No-return readings (+inf) are stored as invalid beams; the fan of beams is centred with the
  sensor's yaw, as MRPT spreads the beams evenly over the aperture (180 beams 1 degree apart from
  -90 degrees are a 179 degree aperture turned by -0.5 degree).
- The settings are in mrpt/rbpf-slam.ini, mrpt/icp-slam.ini and mrpt/pf-localization.ini, one
  comment per choice; a run only sets its output folder, (rbpf-slam) the random seed,
  RANDOM_SEED, which rbpf-slam 2.5.8 reads and gives to MRPT's random generator, and
  (pf-localization) its map, rawlog and starting box.
- Trajectories: icp-slam writes its pose after every scan (log_estimated_path.txt), which is
  final (no loop closure); pf-localization logs its estimate (the particles' mean) at every
  scan, the first being that of the starting cloud. rbpf-slam's answer is the path of the most
  likely particle at the end (most_likely_path.txt, one pose per filter step after the starting
  pose); a scan at which the filter did not run (no motion since the last) gets that path's last
  pose moved by odometry, as rbpf-slam itself predicts it.

- Runs are kept in build/mrpt-peer-runs/, keyed by everything that decides them (the scans, the
  odometry, the seed, the .ini files, this module, the converter's source and the MRPT
  programs): a peer is deterministic given those, and rbpf-slam takes hours over all the logs,
  so the benchmark reruns only what changed. PeerRun.cached says when a run was reused; a run
  that failed by itself (PeerFailed: rbpf-slam out of its memory) is kept as its message, one
  stopped from outside (the timeout, a kill) is not. pf-localization seeds its random generator
  from the clock, so its runs are not kept: the benchmark runs it several times and gives the
  spread.

Runnable alone for a quick check: .venv/bin/python3 benchmarks/mrpt_peers.py [log ...]
"""
import hashlib
import math
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import List, NamedTuple, Optional

import numpy as np

from turtlebot3c_common.se2 import compose, relative

REPO = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent / "mrpt"
CONVERTER_SOURCE = HERE / "scans_to_mrpt.cpp"
CONVERTER = REPO / "build" / "mrpt-converter" / "scans_to_mrpt"
RBPF_CONFIG = HERE / "rbpf-slam.ini"
ICP_CONFIG = HERE / "icp-slam.ini"
PF_CONFIG = HERE / "pf-localization.ini"
SLAM_PEERS = ("rbpf-slam", "icp-slam")
LOCALIZATION_PEERS = ("pf-localization",)
RUNS = REPO / "build" / "mrpt-peer-runs"
MRPT_INCLUDE = Path("/usr/include/mrpt")
MRPT_LIBRARIES = ("mrpt-obs", "mrpt-poses", "mrpt-serialization", "mrpt-io", "mrpt-core",
                  "mrpt-system", "mrpt-math")

# Odometry noise, GMapping's values as ROS gmapping documents them, in MRPT's Gaussian motion
# model (std linear in the distance and the turn, as GMapping's and Thrun's models):
ODOMETRY_NOISE = (0.1,   # a1, m per m: srr
                  0.2,   # a2, m per rad: srt
                  0.1,   # a3, rad per m: str
                  0.2,   # a4, rad per rad: stt
                  0.001,  # m, at least
                  0.001)  # rad, at least
RANGE_STD = 0.01         # m, a SICK LMS's range noise
MAX_RANGE = 30.0         # m: farther readings are dropped as no-return (aces, icp-slam: 30 m beat 80, 15, 8 m)
PEER_TIMEOUT = 3600.0    # s of wall time for one peer run
# rbpf-slam's 30 particle maps of a convention centre (acapulco) grew past 23 GB here and the
# kernel killed it (and could have killed anything else); a peer gets this much, then fails.
PEER_MEMORY = 6 * 1024 ** 3  # bytes of address space
STOPPED_FROM_OUTSIDE = (signal.SIGKILL, signal.SIGTERM, signal.SIGINT)


class PeerFailed(RuntimeError):
    """The peer ended with an error of its own (an exit status, an abort): the same inputs fail again."""


class PeerRun(NamedTuple):
    name: str                 # "rbpf-slam", "icp-slam" or "pf-localization"
    trajectory: np.ndarray    # (N, 3) x, y, theta per scan of the log, in the peer's map frame
                              # (pf-localization's: the reference's, which its map is drawn in)
    seconds: float            # CPU seconds (user + sys) of the peer's process
    peak_rss_mb: float        # the peer process's peak resident memory
    wall_seconds: float
    cached: bool = False      # reused from an earlier run with the very same inputs


def available(programs=SLAM_PEERS) -> Optional[str]:
    """None when the peers `programs` can run here, else why not (one line, for the benchmark to print)."""
    for program in programs:
        if shutil.which(program) is None:
            return f"{program} not found (apt-get install mrpt-apps)"
    try:
        converter()
    except RuntimeError as error:
        return str(error)
    return None


def converter() -> Path:
    """The rawlog converter, compiled on first use (and again when its source changes)."""
    if CONVERTER.exists() and CONVERTER.stat().st_mtime >= CONVERTER_SOURCE.stat().st_mtime:
        return CONVERTER
    compiler = shutil.which("g++")
    if compiler is None:
        raise RuntimeError("g++ not found: cannot build the MRPT rawlog converter")
    if not (MRPT_INCLUDE / "obs" / "include" / "mrpt" / "obs" / "CObservation2DRangeScan.h").exists():
        raise RuntimeError("MRPT headers not found (apt-get install libmrpt-obs-dev)")
    CONVERTER.parent.mkdir(parents=True, exist_ok=True)
    includes = [f"-I{folder}" for folder in sorted(MRPT_INCLUDE.glob("*/include"))]
    includes += ["-I/usr/include/eigen3", "-I/usr/include/suitesparse"]
    # Its own name per process: benchmarks run side by side (one per severity) may build at once.
    partial = CONVERTER.with_name(f"{CONVERTER.name}.{os.getpid()}.partial")
    command = [compiler, "-std=c++17", "-O2", *includes, str(CONVERTER_SOURCE), "-o", str(partial),
               *(f"-l{library}" for library in MRPT_LIBRARIES)]
    built = subprocess.run(command, capture_output=True, text=True)
    if built.returncode != 0:
        tail = (built.stderr.strip().splitlines() or ["(no message)"])[-1]
        raise RuntimeError(f"cannot build the MRPT rawlog converter: {tail}")
    partial.replace(CONVERTER)
    return CONVERTER


def write_rawlog(log, odometry, path, max_range=MAX_RANGE):
    """Convert `log`'s scans with `odometry` (N, 3) into an MRPT rawlog at `path`."""
    odometry = np.asarray(odometry, dtype=np.float64)
    steps = [relative(odometry[index - 1], odometry[index]) if index else (0.0, 0.0, 0.0)
             for index in range(len(odometry))]
    _convert("rawlog", log, range(len(log.stamps)), steps, path, max_range)


def rawlog_in(workdir, log, odometry, max_range=MAX_RANGE) -> Path:
    """The rawlog of `log`'s scans with `odometry` in `workdir`, written once per set of inputs:
    every peer run and AMCL row of a log reads the same scans, and a large log takes a while
    to convert. Named by its inputs, so a folder reused for another severity never serves a
    stale one."""
    digest = _scans_digest(log, odometry)
    digest.update(f"{log.angle_min!r} {log.angle_increment!r} {max_range!r}".encode())
    path = Path(workdir) / f"scans-{digest.hexdigest()[:20]}.rawlog"
    if not path.exists():
        partial = path.with_suffix(".partial")
        write_rawlog(log, odometry, partial, max_range)
        partial.replace(path)
    return path


def write_simplemap(log, poses, scans, path, max_range=MAX_RANGE):
    """The scans of `log` that `scans` (a mask) marks, at their `poses` (N, 3), as an MRPT simplemap at `path`."""
    chosen = np.flatnonzero(scans)
    _convert("simplemap", log, chosen, np.asarray(poses, dtype=np.float64)[chosen], path, max_range)


def _convert(kind, log, indices, poses, path, max_range):
    """The converter's input for the scans `indices` of `log`, each with its row of `poses`, then the converter."""
    beams = log.beams
    aperture = log.angle_increment * (beams - 1)
    sensor_yaw = log.angle_min + aperture / 2.0
    text = Path(str(path) + ".txt")
    with open(text, "w") as stream:
        stream.write(f"{beams} {aperture!r} {sensor_yaw!r} {max_range} {RANGE_STD} "
                     + " ".join(str(value) for value in ODOMETRY_NOISE) + "\n")
        for index, pose in zip(indices, poses):
            readings = np.where(np.isfinite(log.ranges[index]), log.ranges[index], -1.0)
            stream.write(f"{1e9 + float(log.stamps[index]):.6f} {pose[0]!r} {pose[1]!r} {pose[2]!r} ")
            stream.write(" ".join(f"{value:.4f}" for value in readings))
            stream.write("\n")
    done = subprocess.run([str(converter()), kind, str(text), str(path)], capture_output=True, text=True)
    if done.returncode != 0 or done.stdout.strip() != str(len(poses)):
        raise RuntimeError(f"{kind} conversion failed: {done.stderr.strip() or done.stdout.strip()}")
    text.unlink()


def _scans_digest(log, odometry):
    """A sha256 fed with `log`'s scans and `odometry`, to go on feeding."""
    digest = hashlib.sha256()
    for part in (log.stamps, log.ranges, np.asarray(odometry, dtype=np.float64)):
        digest.update(np.ascontiguousarray(part).tobytes())
    return digest


def _kept(name, log, odometry, seed, run):
    """run() unless a run with the same inputs is kept in RUNS; kept afterwards either way."""
    digest = _scans_digest(log, odometry)
    for path in (RBPF_CONFIG, ICP_CONFIG, Path(__file__), CONVERTER_SOURCE, Path(shutil.which(name))):
        digest.update(path.read_bytes())
    digest.update(f"{log.angle_min!r} {log.angle_increment!r} {seed}".encode())
    path = RUNS / f"{name}-{log.name}-{digest.hexdigest()[:20]}.npz"
    failure = path.with_suffix(".failed")
    if failure.exists():
        raise RuntimeError(failure.read_text().strip() + " (kept)")
    if path.exists():
        with np.load(path) as kept:
            return PeerRun(name, kept["trajectory"], float(kept["seconds"]), float(kept["peak_rss_mb"]),
                           float(kept["wall_seconds"]), cached=True)
    RUNS.mkdir(parents=True, exist_ok=True)
    try:
        result = run()
    except PeerFailed as error:  # a crash or running out of memory is as repeatable as a result
        failure.write_text(f"{error}\n")
        raise
    partial = path.with_suffix(".partial.npz")
    np.savez(partial, trajectory=result.trajectory, seconds=result.seconds, peak_rss_mb=result.peak_rss_mb,
             wall_seconds=result.wall_seconds)
    partial.replace(path)
    return result


def run_rbpf_slam(log, odometry, seed, workdir) -> PeerRun:
    """rbpf-slam over every scan of `log` with `odometry` (N, 3), seeded with `seed`."""
    return _kept("rbpf-slam", log, odometry, seed, lambda: _run_rbpf_slam(log, odometry, seed, workdir))


def run_icp_slam(log, odometry, workdir) -> PeerRun:
    """icp-slam over every scan of `log` with `odometry` (N, 3)."""
    return _kept("icp-slam", log, odometry, None, lambda: _run_icp_slam(log, odometry, workdir))


def _run_rbpf_slam(log, odometry, seed, workdir):
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rawlog = rawlog_in(workdir, log, odometry)
    out = workdir / "rbpf-out"
    config = _config(RBPF_CONFIG, workdir / "rbpf-slam.ini",
                     {"logOutput_dir": str(out), "RANDOM_SEED": str(int(seed))})
    seconds, peak, wall = _run(["rbpf-slam", str(config), str(rawlog)], workdir / "rbpf-slam.out")
    path = np.loadtxt(out / "most_likely_path.txt", ndmin=2)
    steps = _filter_steps(odometry, _settings(config))
    if len(path) != int(steps.sum()) + 1:
        raise RuntimeError(f"rbpf-slam: {len(path)} poses in its path for {int(steps.sum())} filter steps")
    trajectory = _fill_between_steps(path[1:], steps, odometry)
    return PeerRun("rbpf-slam", trajectory, seconds, peak, wall)


def _run_icp_slam(log, odometry, workdir):
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rawlog = rawlog_in(workdir, log, odometry)
    out = workdir / "icp-out"
    config = _config(ICP_CONFIG, workdir / "icp-slam.ini", {"logOutput_dir": str(out)})
    seconds, peak, wall = _run(["icp-slam", str(config), str(rawlog)], workdir / "icp-slam.out")
    rows = np.loadtxt(out / "log_estimated_path.txt", comments="%", ndmin=2)
    if len(rows) != len(log.stamps):
        raise RuntimeError(f"icp-slam: {len(rows)} poses for {len(log.stamps)} scans")
    return PeerRun("icp-slam", rows[:, 1:4].copy(), seconds, peak, wall)


def run_pf_localization(log, odometry, map_scans, start, spread, workdir, max_range, runs=1) -> List[PeerRun]:
    """pf-localization `runs` times over every scan of `log` with `odometry` (N, 3), in a map of
    the scans `map_scans` (a mask) at their reference poses, its particles first spread uniformly
    over the free cells within `spread` (m, m, rad) of `start` (x, y, theta). Scans and map keep
    readings up to `max_range` m; both are written once for all the runs. Not kept:
    pf-localization seeds from the clock, so every run differs."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rawlog, simplemap = rawlog_in(workdir, log, odometry, max_range), workdir / "map.simplemap"
    write_simplemap(log, log.reference, map_scans, simplemap, max_range)
    (x, y, theta), (half_x, half_y, half_theta) = start, spread
    done = []
    for run in range(runs):
        config = _config(PF_CONFIG, workdir / f"pf-localization-{run}.ini", {
            "map_file": str(simplemap), "rawlog_file": str(rawlog), "logOutput_dir": str(workdir / f"pf-out-{run}"),
            "init_PDF_min_x": x - half_x, "init_PDF_max_x": x + half_x,
            "init_PDF_min_y": y - half_y, "init_PDF_max_y": y + half_y,
            "init_PDF_min_yaw_deg": math.degrees(theta - half_theta),
            "init_PDF_max_yaw_deg": math.degrees(theta + half_theta)}, section_name="[LocalizationExperiment]")
        output = workdir / f"pf-localization-{run}.out"
        seconds, peak, wall = _run(["pf-localization", str(config)], output)
        estimates = pf_localization_estimates(output.read_text(errors="replace"))
        if len(estimates) != len(log.stamps):
            raise RuntimeError(f"pf-localization: {len(estimates)} estimates for {len(log.stamps)} scans")
        done.append(PeerRun("pf-localization", estimates, seconds, peak, wall))
    return done


# pf-localization's log line with its estimate after each scan: "PDF estimation: (x,y,theta_deg), ..."
PF_ESTIMATE = re.compile(r"PDF estimation: \(([-+\d.eE]+),([-+\d.eE]+),([-+\d.eE]+)deg\)")


def pf_localization_estimates(output):
    """(N, 3) x, y, theta (rad) per scan from pf-localization's log."""
    rows = [[float(value) for value in match.groups()] for match in PF_ESTIMATE.finditer(output)]
    estimates = np.array(rows, dtype=float).reshape(-1, 3)
    estimates[:, 2] = np.radians(estimates[:, 2])
    return estimates


def _run(command, output):
    """Run a peer to completion: (CPU s of user + sys, peak RSS MB, wall s) of its process."""
    started = time.monotonic()
    with open(output, "w") as stream:
        process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=stream,
                                   stderr=subprocess.STDOUT, cwd=output.parent,
                                   env={**os.environ, "DISPLAY": ""}, preexec_fn=_limit_memory)
        deadline = started + PEER_TIMEOUT
        while True:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                process.kill()
                _, status, usage = os.wait4(process.pid, 0)
                break
            time.sleep(0.05)
    # subprocess's convention (minus the signal), by hand: os.waitstatus_to_exitcode is 3.9's.
    process.returncode = -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)
    wall = time.monotonic() - started
    if process.returncode != 0:
        tail = output.read_text(errors="replace").strip().splitlines()[-3:]
        # Killed or stopped from outside (the timeout, the kernel's OOM killer, a person) is not
        # the peer's own answer to these inputs; an exit or an abort (out of its memory) is.
        failure = RuntimeError if -process.returncode in STOPPED_FROM_OUTSIDE else PeerFailed
        raise failure(f"{command[0]} exited with {process.returncode} after {wall:.0f} s, peak RSS "
                      f"{usage.ru_maxrss / 1024:.0f} MB of {PEER_MEMORY / 1024 ** 3:.0f} GB allowed: "
                      + " | ".join(tail))
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, wall


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (PEER_MEMORY, PEER_MEMORY))


def _config(template, path, values, section_name="[MappingApplication]"):
    """A copy of an .ini file with some keys of one section set to `values`."""
    lines, section, seen = [], None, set()
    for line in template.read_text().splitlines():
        stripped = line.strip()
        if stripped.startswith("["):
            section = stripped
        key = stripped.split("=", 1)[0].strip() if "=" in stripped and not stripped.startswith("#") else None
        if section == section_name and key in values:
            line = f"{key} = {values[key]}"
            seen.add(key)
        lines.append(line)
    missing = set(values) - seen
    if missing:
        raise ValueError(f"{template}: no {', '.join(sorted(missing))} in {section_name}")
    path.write_text("\n".join(lines) + "\n")
    return path


def _settings(config):
    """The filter-step thresholds of an rbpf-slam .ini: (localize m, localize rad, insert m, insert rad)."""
    values = {}
    section = None
    for line in config.read_text().splitlines():
        stripped = line.split("//", 1)[0].strip()
        if stripped.startswith("["):
            section = stripped
        elif section == "[MappingApplication]" and "=" in stripped and not stripped.startswith("#"):
            key, value = (part.strip() for part in stripped.split("=", 1))
            values[key] = value
    return (float(values["localizeLinDistance"]), math.radians(float(values["localizeAngDistance_deg"])),
            float(values["insertionLinDistance"]), math.radians(float(values["insertionAngDistance_deg"])))


def _filter_steps(odometry, settings):
    """(N,) bool: at which scans rbpf-slam runs its filter (CMetricMapBuilderRBPF's rule: the
    first scan, and whenever odometry since the last filter step or map update passes a threshold)."""
    localize_xy, localize_yaw, insert_xy, insert_yaw = settings
    steps = np.zeros(len(odometry), dtype=bool)
    since_localized = since_inserted = (0.0, 0.0, 0.0)
    for index in range(len(odometry)):
        step = relative(odometry[index - 1], odometry[index]) if index else (0.0, 0.0, 0.0)
        since_localized = compose(since_localized, step)
        since_inserted = compose(since_inserted, step)
        insert = index == 0 or math.hypot(*since_inserted[:2]) > insert_xy or abs(since_inserted[2]) > insert_yaw
        localize = insert or math.hypot(*since_localized[:2]) > localize_xy or abs(since_localized[2]) > localize_yaw
        if localize:
            steps[index] = True
            since_localized = (0.0, 0.0, 0.0)
        if insert:
            since_inserted = (0.0, 0.0, 0.0)
    return steps


def _fill_between_steps(path, steps, odometry):
    """A pose per scan from the filter's poses at its steps, moving by odometry in between."""
    trajectory = np.zeros((len(steps), 3))
    poses = iter(path)
    last_pose, last_index = None, None
    for index, stepped in enumerate(steps):
        if stepped:
            last_pose, last_index = tuple(next(poses)), index
            trajectory[index] = last_pose
        else:
            trajectory[index] = compose(last_pose, relative(odometry[last_index], odometry[index]))
    return trajectory


def main(names):
    """Quick check: both peers on some logs with severe odometry, scored as our SLAM is."""
    from testkit.real_data import load_log, score
    from turtlebot3c_sim.odometry_error import SEVERITIES, noisy_odometry

    reason = available()
    if reason:
        print(f"MRPT peers unavailable: {reason}")
        return 1
    for name in names or ["aces", "freiburg-101"]:
        log = load_log(name)
        odometry = noisy_odometry(log.reference, SEVERITIES["severe"], 0)
        odo = score(log, odometry)
        print(f"{name}: {len(log.stamps)} scans; odometry {odo.translation:.3f} m {odo.rotation:.2f} deg")
        with tempfile.TemporaryDirectory(prefix="mrpt-peers-") as folder:
            for run in (run_rbpf_slam(log, odometry, 0, folder), run_icp_slam(log, odometry, folder)):
                result = score(log, run.trajectory)
                print(f"  {run.name:9s} {result.translation:.3f} m {result.rotation:.2f} deg "
                      f"ATE {result.ate:.3f} m  cpu {run.seconds:.1f} s  wall {run.wall_seconds:.1f} s  "
                      f"rss {run.peak_rss_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.path[:0] = [str(REPO)] + [str(REPO / "src" / package / "src") for package in
                                  ("turtlebot3c_common", "turtlebot3c_sim", "turtlebot3c_slam", "turtlebot3c_maps")]
    sys.exit(main(sys.argv[1:]))
