"""``humv-usd bench detector``: a sweep's dataset -> a person detector trained on the CPU and
scored on held-out variants (issue 27 deliverable 3; :mod:`humv_usd.bench.detector`)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors

#: the default sweep: 32 variants of a walking person among warm props, 3 frames each
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "detector" / "sweep.toml"


@click.command("detector")
@click.argument("source", required=False, type=click.Path(exists=True, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out_dir",
    default="out/detector",
    show_default=True,
    help="Dataset folder the sweep writes (resumed when it exists); unused when SOURCE is a dataset.",
)
@click.option("--sensor", default=None, help="Sensor whose images to use (default: the first with people).")
@click.option("--workers", default=0, show_default=True, type=click.IntRange(0, 4096), help="Sweep workers.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1))
@click.option("--json", "json_file", default=None, help="Also write the report as JSON to this file.")
@reports_errors
def bench_detector(source, out_dir: str, sensor, workers: int, seed: int, json_file):
    """Generate a dataset with a sweep (SOURCE a sweep file; default examples/detector/sweep.toml)
    or take a finished one (SOURCE a dataset folder), train a HOG + linear SVM person detector on
    its train split on the CPU (C chosen on val) and print pycocotools' AP50 per split: val and
    test are held-out variants. Needs the detector extra: pip install -e '.[detector]'."""
    from humv_usd.bench.detector import _libraries, bench_detector
    from humv_usd.fileio import check_output_file, write_text_atomic

    _libraries()  # before a sweep runs: the extra is missing -> one line
    if json_file is not None:
        check_output_file(json_file, "--json")
    source = EXAMPLE if source is None else source
    if source.is_dir():
        dataset = source
    else:
        from humv_usd.cli.sweep_cmd import _Progress
        from humv_usd.fileio import check_output_dir
        from humv_usd.sweep.run import run_sweep
        from humv_usd.sweep.spec import load_sweep

        check_output_dir(out_dir, "dataset folder")
        sweep = load_sweep(source)
        with _Progress(quiet=False) as progress:
            result = run_sweep(sweep, out_dir, workers=workers, on_event=progress)
        if result.failures:
            for f in result.failures:
                click.echo(f"  failed: {f['task']}: {f['error']}", err=True)
            raise SystemExit(1)
        dataset = Path(out_dir)
        click.echo(f"{dataset}: {result.dataset_summary['images']} images, {result.seconds:.1f} s", err=True)
    report = bench_detector(dataset, sensor, seed, on_line=lambda text: click.echo(text, err=True))
    click.echo(
        f"{report['detector']}; sensor {report['sensor']}, C = {report['C']:g} ({report['C_chosen_on']}), "
        f"trained in {report['train_seconds']:.1f} s"
    )
    click.echo(f"{'split':<6} {'variants':>8} {'images':>6} {'people':>6} {'AP50':>6} {'AP':>6} {'AR100':>6}")
    for name, s in report["splits"].items():
        click.echo(
            f"{name:<6} {len(s['variants']):>8} {s['images']:>6} {s['people']:>6} "
            f"{s['AP50']:>6.3f} {s['AP']:>6.3f} {s['AR100']:>6.3f}"
        )
    if json_file is not None:
        write_text_atomic(json_file, json.dumps(report, indent=2) + "\n")
