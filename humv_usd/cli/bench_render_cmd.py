"""``humv-usd bench render``: the sub-band model's spectral error, and the IR estimators' Monte
Carlo error and bias against run time (:mod:`humv_usd.bench.render`), with PNG curves."""

from __future__ import annotations

import tempfile
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors
from humv_usd.errors import InputError


def _k(value, fmt="{:.4f}") -> str:
    return "n/a" if value is None else fmt.format(value)


def _ints(text, name, check=None):
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--{name} = {text!r}: expected comma-separated integers") from None
    if not values:
        raise InputError(f"--{name} = {text!r}: expected at least one integer")
    for v in values:
        if check is not None:
            check(v, f"--{name}")
        elif v < 1:
            raise InputError(f"--{name} = {v}: expected integers >= 1")
    return values


@click.command("render")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--spp", "spp_text", default="1,2,4,8", show_default=True, help="Camera samples per pixel to sweep."
)
@click.option(
    "--subbands",
    "sub_text",
    default="4,8,16",
    show_default=True,
    help="Sub-band counts to sweep (and tabulate).",
)
@click.option("--reference-spp", default=256, show_default=True, type=click.IntRange(2, 1 << 16))
@click.option("--reference-subbands", default=16, show_default=True, type=click.IntRange(1, 64))
@click.option("--sensor", "sensors", multiple=True, help="Only this IR or EO sensor (repeatable).")
@click.option(
    "--eo-spp",
    "eo_spp_text",
    default="2,4,8",
    show_default=True,
    help="EO: camera samples per pixel to sweep.",
)
@click.option(
    "--eo-bins",
    "eo_bins_text",
    default="4,8,12,16",
    show_default=True,
    help="EO: visible sub-band counts to sweep.",
)
@click.option("--eo-reference-spp", default=64, show_default=True, type=click.IntRange(2, 1 << 16))
@click.option(
    "--eo-scale",
    default=1.0,
    show_default=True,
    type=click.FloatRange(0.05, 1.0),
    help="EO: render at this fraction of the sensors' resolution (quick looks).",
)
@click.option(
    "--atmosphere-model",
    default=None,
    type=click.Choice(["lowtran7", "analytic"]),
    help="Override [atmosphere] model (default: the scenario's).",
)
@click.option(
    "-o",
    "--out",
    "out_prefix",
    default="render_bench",
    show_default=True,
    help="Output prefix: PREFIX.json (every number) and PREFIX.png (error against run time per sensor).",
)
@reports_errors
def bench_render(
    scenario: Path,
    spp_text,
    sub_text,
    reference_spp,
    reference_subbands,
    sensors,
    eo_spp_text,
    eo_bins_text,
    eo_reference_spp,
    eo_scale,
    atmosphere_model,
    out_prefix,
):
    """Error against run time of the infrared render of SCENARIO's first frame.

    Composes SCENARIO, prints the spectral error of the sub-band model, then renders every IR
    sensor with the plain path tracer as the reference (--reference-spp, --reference-subbands) and
    with the fast estimator for every --spp x --subbands pair: wall time, ratio to the pixel-centre
    ray cast, mean / p99 per-pixel error in K away from edges (edges apart) and the bias per
    labelled region against the reference. EO sensors likewise: the spectral path tracer at
    --eo-reference-spp as the reference, the fast estimator for every --eo-spp x --eo-bins pair,
    the error of Y relative to the mean Y and the relative bias of X, Y, Z per region.
    """
    from humv_usd.bench.render import bench_render as run_bench
    from humv_usd.bench.render import plot_error_vs_time
    from humv_usd.bench.render_eo import bench_render_eo, plot_eo_error_vs_time
    from humv_usd.bench.subbands import subband_error_table
    from humv_usd.fileio import write_json
    from humv_usd.pipeline.compose import compose as run_compose
    from humv_usd.scenario import load_scenario
    from humv_usd.usd.sensor import check_subbands

    spp_list = _ints(spp_text, "spp")
    eo_spp_list = _ints(eo_spp_text, "eo-spp")
    eo_bins_list = _ints(eo_bins_text, "eo-bins", _check_bins)
    sub_list = _ints(sub_text, "subbands", check_subbands)
    sc = load_scenario(scenario)
    if atmosphere_model is not None:
        sc["atmosphere"]["model"] = atmosphere_model
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "stage"
        run_compose(sc, out)
        stage = out / "stage.usda"
        table = subband_error_table(stage, sorted(set(sub_list) | {1, 2}))
        click.echo(
            f"scenario {scenario}: spectral error of the sub-band model [K] (max / rms over materials, temperatures, ranges)"
        )
        for name, row in table["sensors"].items():
            cells = "  ".join(
                f"n={n}: {e['max_k']:.3f}/{e['rms_k']:.3f}" for n, e in row["error_by_subbands"].items()
            )
            click.echo(f"  {name:<16} {cells}")
        result = run_bench(
            stage,
            spp_list,
            sub_list,
            reference_spp=reference_spp,
            reference_subbands=reference_subbands,
            sensors=list(sensors) or None,
            progress=lambda text: click.echo(f"  ... {text}", err=True),
        )
        eo_result = bench_render_eo(
            stage,
            eo_spp_list,
            eo_bins_list,
            reference_spp=eo_reference_spp,
            sensors=list(sensors) or None,
            progress=lambda text: click.echo(f"  ... {text}", err=True),
            scale=eo_scale,
        )
    result["spectral_error"] = table
    result["eo"] = eo_result
    for name, rec in result["sensors"].items():
        click.echo(
            f"{name} ({rec['band']}, NETD {rec['netd_k']} K): pixel-centre ray cast {rec['ray_cast_s']:.3f} s; "
            f"reference path {rec['reference']['spp']} spp / {rec['reference']['subbands']} sub-bands "
            f"{rec['reference']['wall_s']:.1f} s, its own error {_k(rec['reference']['noise']['mean_k'])} K"
        )
        click.echo(
            "  estimator  spp  sb   wall s  cpu s  x cast  mean K   p99 K  edge K  |bias| max K (region: bias +- sigma)"
        )
        for r in rec["rows"]:
            nz = r["noise"]
            bias = r["bias_by_region"]
            worst = max(bias.values(), key=lambda b: abs(b["bias_k"]))
            regions = ", ".join(f"{k}: {v['bias_k']:+.4f}+-{v['sigma_k']:.4f}" for k, v in bias.items())
            mark = " *" if r["default"] else ""
            click.echo(
                f"  {r['estimator']:<9} {r['spp']:>4} {r['subbands']:>3} {r['wall_s']:>7.2f} {r['cpu_s']:>6.2f} "
                f"{r['ratio_to_ray_cast']:>7.1f} {_k(nz['mean_k'])}  {_k(nz['p99_k'])}  {_k(nz['edge_mean_k'], '{:.3f}')}  "
                f"{abs(worst['bias_k']):.4f} ({regions}){mark}"
            )
    _echo_eo(eo_result)
    write_json(f"{out_prefix}.json", result)
    wrote = f"{out_prefix}.json"
    if result["sensors"]:
        plot_error_vs_time(result, f"{out_prefix}.png")
        wrote += f", {out_prefix}.png"
    if eo_result["sensors"]:
        plot_eo_error_vs_time(eo_result, f"{out_prefix}_eo.png")
        wrote += f", {out_prefix}_eo.png"
    click.echo(f"wrote {wrote}  (* = the default setting)")


def _check_bins(v, name):
    from humv_usd.render.eo_fast import GRID_NM

    if not 1 <= v <= GRID_NM.size:
        raise InputError(f"{name} = {v}: expected integers in 1..{GRID_NM.size}")


def _pct(value) -> str:
    return "n/a" if value is None else f"{100 * value:.3f}"


def _echo_eo(eo_result: dict) -> None:
    for name, rec in eo_result["sensors"].items():
        ref = rec["reference"]
        click.echo(
            f"{name} (EO {rec['resolution'][0]}x{rec['resolution'][1]}): pixel-centre ray cast "
            f"{rec['ray_cast_s']:.3f} s; reference spectral path {ref['spp']} spp {ref['wall_s']:.1f} s, "
            f"its own error {_pct(ref['noise']['mean'])} % of mean Y"
        )
        click.echo(
            "  estimator  spp bins  wall s  cpu s  x cast  mean %   p99 %  edge %  |bias| max % "
            "(region: X, Y, Z bias % , sigma Y %)"
        )
        for r in rec["rows"]:
            nz, bias = r["noise"], r["bias_by_region"]
            worst = max(abs(v) for b in bias.values() for v in b["bias_rel_xyz"] if v is not None)
            regions = ", ".join(
                f"{k}: " + "/".join(_pct(v) for v in b["bias_rel_xyz"]) + f" +-{_pct(b['sigma_rel_y'])}"
                for k, b in bias.items()
            )
            mark = " *" if r["default"] else ""
            bins = "-" if r["bins"] is None else r["bins"]
            click.echo(
                f"  {r['estimator']:<9} {r['spp']:>4} {bins:>4} {r['wall_s']:>7.2f} {r['cpu_s']:>6.2f} "
                f"{r['ratio_to_ray_cast']:>7.1f} {_pct(nz['mean'])}  {_pct(nz['p99'])}  {_pct(nz['edge_mean'])}  "
                f"{100 * worst:.3f} ({regions}){mark}"
            )
