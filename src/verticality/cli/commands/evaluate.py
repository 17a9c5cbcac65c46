"""``verticality evaluate broad DIR [--json] [--workers N] [--scheduler ADDRESS]``: official BROAD
inclination RMSE per trial and the mean, for our filter and the installed peers (vqf, madgwick,
mahony), and for the offline estimators (our smoother, vqf's offlineVQF), in the same run; with
``--workers`` or ``--scheduler`` one Dask task per trial (the same table)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from verticality.cli.commands import add_engine_arguments, print_table


def register(sub):
    p = sub.add_parser("evaluate", help="score tilt filters on recorded benchmarks")
    ev = p.add_subparsers(dest="benchmark", metavar="BENCHMARK")
    ev.required = True
    b = ev.add_parser("broad", help="BROAD inclination RMSE per trial (official metric)")
    b.add_argument("directory", type=Path, metavar="DIR", help="folder of BROAD .hdf5 trials")
    b.add_argument("--json", action="store_true",
                   help='print {"trials": {NAME: {FILTER: rmse_deg}}, "mean": {FILTER: rmse_deg}}')
    b.add_argument("--filters", nargs="+", default=None, metavar="NAME",
                   help="filters to run (default: verticality, every installed peer, "
                        "verticality-offline (our smoother) and vqf-offline (offlineVQF))")
    add_engine_arguments(b, "one task per trial", "the trials one after the other in this process")
    b.set_defaults(func=run_broad)


def run_broad(args) -> int:
    from rich.console import Console
    from rich.table import Table

    from verticality.io import broad
    from verticality.tilt.evaluation.broad import (
        OURS,
        OURS_OFFLINE,
        choose_filters,
        evaluate_trials,
    )

    err = Console(stderr=True)
    paths = broad.list_trials(args.directory)
    filters, notes = choose_filters(args.filters)
    for note in notes:
        err.print(note)
    res = evaluate_trials(paths, filters, progress=lambda msg: err.print(f"running {msg} …"),
                          scheduler=args.scheduler, workers=args.workers)
    # our filter's and our smoother's reported σ against their errors (docs/tilt.md)
    sigmas = {name: res[key] for name, key in ((OURS, "sigma"), (OURS_OFFLINE, "sigma_offline"))
              if res[key]}
    if args.json:
        # our filter's and smoother's σ calibration beside the errors: {FILTER: {NAME: {...}}}
        json.dump({"trials": res["trials"], "mean": res["mean"], "sigma": sigmas}, sys.stdout,
                  indent=2)
        sys.stdout.write("\n")
        return 0
    table = Table(title=f"BROAD inclination RMSE (deg), {len(res['trials'])} trials")
    table.add_column("trial", no_wrap=True)
    for f in filters:
        table.add_column(f, justify="right", no_wrap=True)
    for f in sigmas:
        table.add_column(f"{f}: RMS σ", justify="right", no_wrap=True)
        table.add_column("within σ / 2σ", justify="right", no_wrap=True)
    best = {name: min(v.values()) for name, v in res["trials"].items()}
    for name, v in res["trials"].items():
        cells = [(f"[bold]{v[f]:.3f}[/bold]" if v[f] == best[name] else f"{v[f]:.3f}")
                 for f in filters]
        for sig in sigmas.values():
            c = sig[name]
            cells += [f"{c['rms_sigma_deg']:.3f}",
                      f"{100 * c['within_1sigma']:.1f} / {100 * c['within_2sigma']:.1f} %"]
        table.add_row(name, *cells)
    table.add_row("mean", *[f"{res['mean'][f]:.3f}" for f in filters], end_section=True)
    table.add_row("runtime (s)", *[f"{res['runtime_s'][f]:.2f}" for f in filters])
    print_table(table)
    if sigmas:
        Console().print("within σ / 2σ: the share of scored samples whose error is at most the "
                        "reported σ / 2σ (0.632 / 0.982 if σ were exact for a 2-D Gaussian error)")
    return 0
