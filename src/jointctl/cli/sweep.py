"""``jointctl sweep``: one scenario run per sample of what varies, on Dask distributed; results.csv, summary.json
and figures."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jointctl.cli.common import CONTROLLERS_HELP, SET_VALUES, TARGET_HELP

VARY_HELP = ("FIELD=VALUES: a scenario field as --set reaches it (payload_kg, model.LINK.mass (ixx ... iyz), "
             "model.JOINT.damping (friction, armature), latency_cycles, noise.position, noise.velocity, gravity, "
             "controllers.NAME.pid.p...); VALUES a grid a:b:n, a list a,b,c or [a, b, c], uniform(a, b) or "
             "normal(mu, sigma) (repeatable: grids make a full factorial)")


def add_parsers(sub) -> None:
    sweep = sub.add_parser("sweep", help="run a scenario over a grid or a distribution of gains, plant, payload, "
                                         "latency and noise, on Dask (this machine's cores or a cluster)")
    sweep.add_argument("target", help=TARGET_HELP)
    sweep.add_argument("--vary", action="append", default=[], metavar="FIELD=VALUES", help=VARY_HELP)
    sweep.add_argument("--samples", type=int, default=None,
                       help="draws of the distributions at each grid point (needed with a distribution)")
    sweep.add_argument("--seed", type=int, default=0, help="seed of the draws and the sensor noise (default 0)")
    sweep.add_argument("--spec", default=None, metavar="METRIC<=X,...",
                       help="what a run must meet to pass, e.g. overshoot_pct<=10,settling_time_s<=0.3")
    sweep.add_argument("--workers", type=int, default=None,
                       help="run on a local cluster of this many worker processes (default: one per core, when the "
                            "runs take longer than the cluster's start; else in this process)")
    sweep.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="submit to a running Dask cluster (tcp://host:8786) instead of starting one here")
    sweep.add_argument("--in-process", action="store_true", help="run here, one run after the other, without Dask")
    sweep.add_argument("--out", type=Path, help="output folder (default: out/sweep_<scenario name>)")
    sweep.add_argument("--no-figures", action="store_true", help="write results.csv and summary.json only")
    sweep.add_argument("--controllers", default=None, help=CONTROLLERS_HELP)
    sweep.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help=f"override a scenario field in every run; {SET_VALUES}")
    sweep.add_argument("--package-path", action="append", default=[], metavar="DIR",
                       help="folder searched for $(find pkg) and package:// (repeatable)")
    sweep.set_defaults(handler=_sweep)


def _sweep(args: argparse.Namespace) -> int:
    from jointctl.recording.metrics_file import metrics_json
    from jointctl.scenario.targets import resolve_target
    from jointctl.sweep import run_sweep

    name = resolve_target(args.target, controllers=args.controllers, overrides=args.overrides,
                          robot_defaults=["duration_s=5"]).scenario.name
    out = args.out or Path("out") / f"sweep_{name}"
    result = run_sweep(args.target, args.vary, samples=args.samples, seed=args.seed, spec=args.spec,
                       scheduler=args.scheduler, workers=args.workers, in_process=args.in_process, out_dir=out,
                       controllers=args.controllers, overrides=args.overrides, package_path=args.package_path,
                       figures=not args.no_figures, progress=True,
                       say=lambda line: print(f"jointctl: {line}", file=sys.stderr, flush=True))
    summary = result.summary()
    shown = {k: summary[k] for k in ("runs", "finished", "passed", "failed", "errors", "errors_by_kind")}
    shown["worst"] = {m: entry["worst"] for m, entry in summary["metrics"].items()
                      if "worst" in entry and result.spec.term(m) is not None}
    print(metrics_json(shown))
    if result.interrupted:
        print(f"jointctl: interrupted after {len(result.rows)} of {result.planned} runs; wrote the finished ones "
              f"to {out}/", file=sys.stderr)
        return 130
    print(f"wrote {out}/ ({len(result.rows)} runs on {result.engine} in {result.wall_s:.1f} s)", file=sys.stderr)
    return 0
