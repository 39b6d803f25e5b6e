"""aco-sweep: a `sitl sweep` across a Ray cluster, one Ray task per shard, merged into the whole sweep.

Each task runs the `sitl` binary on one shard (`sitl sweep SPEC --shard K/N`) and returns its rows; the
driver writes the shards' row files and has `sitl sweep SPEC --merge ...` check them against the spec
(every run once, each with the values the spec gives it) and write the merged rows, the robustness
table and the plots. The merged rows equal a single-process `sitl sweep SPEC` row for row, because each
run's values and seed come from the sweep seed and the run's index alone.

Without `--ray-address` the sweep runs locally: `sitl sweep SPEC` on every core of this machine.

On a cluster, every node needs the `sitl` binary at the path `--sitl` gives (or on its PATH) and the
Python with Ray that the cluster runs; the spec and its scenario file travel with the tasks.

    aco-sweep sitl/sweeps/gust-robustness.toml --ray-address 10.0.0.5:6379 --shards 16
"""

from __future__ import annotations

import argparse
import logging
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

BUILT_IN_SCENARIOS = ("paper-attitude", "paper-translation", "gust-hover", "turbulence-hover", "figure8")


def find_sitl(given: str | None) -> str:
    """The sitl binary: the one given, else on PATH, else this checkout's release or test build."""
    if given:
        return given
    on_path = shutil.which("sitl")
    if on_path:
        return on_path
    root = Path(__file__).resolve().parents[2]
    for profile in ("release", "debug"):
        candidate = root / "target" / profile / "sitl"
        if candidate.exists():
            return str(candidate)
    sys.exit("aco-sweep: no `sitl` binary: give --sitl PATH (cargo build --release -p sitl builds it)")


def scenario_file(spec_path: Path) -> Path | None:
    """The scenario file a spec names, or None for a built-in scenario."""
    with spec_path.open("rb") as f:
        spec = tomllib.load(f)
    name = spec.get("scenario")
    if not isinstance(name, str):
        sys.exit(f"aco-sweep: {spec_path}: `scenario` must name a built-in scenario or a file")
    if name in BUILT_IN_SCENARIOS:
        return None
    return spec_path.parent / name


def run_shard(sitl: str, spec_text: str, scenario_text: str | None, k: int, n: int, jobs: int) -> str:
    """One shard on this node: the spec (and scenario) written to a scratch directory; returns the rows."""
    with tempfile.TemporaryDirectory(prefix="aco-sweep-") as tmp:
        spec = Path(tmp) / "spec.toml"
        spec.write_text(spec_text)
        cmd = [sitl, "sweep", str(spec), "--shard", f"{k}/{n}", "--out", tmp, "--no-plots", "--jobs", str(jobs)]
        if scenario_text is not None:
            scenario = Path(tmp) / "scenario.toml"
            scenario.write_text(scenario_text)
            cmd += ["--scenario", str(scenario)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"shard {k}/{n}: {' '.join(cmd)} failed:\n{done.stderr}")
        return (Path(tmp) / f"runs-shard-{k}-of-{n}.csv").read_text()


def run_on_ray(args: argparse.Namespace, sitl: str, out: Path) -> list[Path]:
    """Every shard as a Ray task; their rows written to out/shards/. Returns the shard files in order."""
    import ray  # imported here: the local mode needs no Ray

    spec_path = Path(args.spec)
    scenario = scenario_file(spec_path)
    spec_text = spec_path.read_text()
    scenario_text = scenario.read_text() if scenario else None
    # The task travels by value, so the nodes need Ray but not this package.
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    ray.init(address=args.ray_address, logging_level=logging.WARNING, log_to_driver=False)
    try:
        n = args.shards or max(1, int(ray.cluster_resources().get("CPU", 1)) // args.jobs_per_shard)
        task = ray.remote(run_shard).options(num_cpus=args.jobs_per_shard, max_retries=1)
        pending = {task.remote(sitl, spec_text, scenario_text, k, n, args.jobs_per_shard): k for k in range(1, n + 1)}
        shards_dir = out / "shards"
        shards_dir.mkdir(parents=True, exist_ok=True)
        files: dict[int, Path] = {}
        start = time.monotonic()
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            k = pending.pop(ready[0])
            path = shards_dir / f"runs-shard-{k}-of-{n}.csv"
            tmp = path.with_suffix(".csv.tmp")
            tmp.write_text(ray.get(ready[0]))
            tmp.replace(path)
            files[k] = path
            elapsed_s = time.monotonic() - start
            print(f"aco-sweep: shard {k}/{n} done ({len(files)} of {n}, {elapsed_s:.1f} s)", file=sys.stderr)
        return [files[k] for k in sorted(files)]
    finally:
        ray.shutdown()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="aco-sweep", description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter
    )
    p.add_argument("spec", help="the sweep spec (TOML, as for `sitl sweep`)")
    p.add_argument("--ray-address", help="the Ray cluster (host:port, or `auto`); without it: locally, all cores")
    p.add_argument("--shards", type=int, help="shards, one Ray task each (default: the cluster's CPUs)")
    p.add_argument("--jobs-per-shard", type=int, default=1, help="threads (and Ray CPUs) per shard (default 1)")
    p.add_argument("--out", help="output directory (default: out/sweep-<name>)")
    p.add_argument("--sitl", help="the sitl binary (default: on PATH, else target/{release,debug}/sitl)")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    args = p.parse_args(argv)
    if args.shards is not None and args.shards < 1:
        p.error("--shards must be at least 1")
    if args.jobs_per_shard < 1:
        p.error("--jobs-per-shard must be at least 1")
    sitl = find_sitl(args.sitl)
    spec = Path(args.spec)
    if not spec.is_file():
        p.error(f"no spec file {spec}")
    with spec.open("rb") as f:
        name = tomllib.load(f).get("name", spec.stem)
    out = Path(args.out) if args.out else Path("out") / f"sweep-{name}"
    plots = ["--no-plots"] if args.no_plots else []
    if not args.ray_address:
        return subprocess.run([sitl, "sweep", str(spec), "--out", str(out), *plots]).returncode
    files = run_on_ray(args, sitl, out)
    merge = [sitl, "sweep", str(spec), "--out", str(out), *plots, "--merge", *map(str, files)]
    return subprocess.run(merge).returncode


if __name__ == "__main__":
    sys.exit(main())
