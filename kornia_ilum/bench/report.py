r"""The tables and the figure of ``kornia-ilum bench``: Markdown, JSON and a run-time-against-error Pareto PNG.

:data:`PAPER` holds the numbers of LeGendre et al. 2020 that the project's issues cite, printed beside ours and
labelled as what they are: another dataset (real light-stage subjects under real lighting, not this project's
MakeHuman light stage) and another device (a phone's CPU, not this machine).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from kornia_ilum.core.files import atomic_write

__all__ = ["PAPER", "bench_figure", "format_bench", "format_skips", "pareto_front", "write_bench"]

#: The paper's published numbers as this project cites them (issues 21 and 23): its diffuse ``L_rec`` and its
#: real-time rate. Not comparable to ours: another dataset and another device.
PAPER: dict[str, Any] = {
    "source": "LeGendre et al. 2020, 'Learning Illumination from Diverse Portraits', as cited in the project's "
              "issues 21 and 23",
    "dataset": "real light-stage subjects relit by real HDR maps (not this project's MakeHuman light stage)",
    "device": "a phone CPU (not this machine)",
    "diffuse_l_rec": 0.069,
    "fps": 27.5,
    "ms_per_frame": 1000 / 27.5,
}


def _f(x: float | None, digits: int = 4) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def pareto_front(rows: list[dict[str, Any]]) -> list[str]:
    """The labels of the rows that no other row beats on both batch-1 time and diffuse ``L_rec``.

    Errors equal to 4 decimals tie, so a row only faster than another on the same error is on the front alone.

    Args:
        rows: bench rows (:func:`~kornia_ilum.bench.run_bench`'s ``rows``) with ``label``, ``b1_ms_per_crop``
            and ``l_rec`` (``{"diffuse": ...}``); a row without a time or an error is left out.

    Returns:
        the labels of the front, in the order of ``rows``.

    Examples:
        >>> rows = [{"label": "a", "b1_ms_per_crop": 1.0, "l_rec": {"diffuse": 0.2}},
        ...         {"label": "b", "b1_ms_per_crop": 2.0, "l_rec": {"diffuse": 0.1}},
        ...         {"label": "c", "b1_ms_per_crop": 3.0, "l_rec": {"diffuse": 0.3}}]
        >>> pareto_front(rows)
        ['a', 'b']
    """
    timed = [(r["label"], r["b1_ms_per_crop"], round(r["l_rec"]["diffuse"], 4)) for r in rows
             if r.get("b1_ms_per_crop") is not None and r.get("l_rec")]  # errors equal to 4 decimals tie
    return [label for label, t, e in timed
            if not any(ot <= t and oe <= e and (ot < t or oe < e) for _, ot, oe in timed)]


def format_skips(rows: list[dict[str, Any]], what: str) -> str:
    """The ``skips`` section (:func:`~kornia_ilum_lab.bench.skips.skip_rows`) as Markdown, or ``what`` alone when
    nothing was measured.

    Args:
        rows: the rows of :func:`~kornia_ilum_lab.bench.skips.skip_rows`.
        what: its line saying what they were measured on (or why nothing was).

    Returns:
        the section: a title, ``what`` and one table row per row; ``what`` and a full stop without rows.

    Examples:
        >>> format_skips([], "skips: not measured")
        'skips: not measured.'
        >>> row = {"skip": "sparse relighting", "setting": "dense", "ms": 4.0, "speedup": 1.0,
        ...        "error": {"l_rec_like": 0.0, "l_rec_like_max": 0.0, "lights_kept": 64.0, "maps": 2}}
        >>> print(format_skips([row], "eval subject 3").splitlines()[-1])
        | sparse relighting | dense | 4.00 | 1.00 | L_rec-like 0.00 % (worst map 0.00 %); 64.0 lights kept; 2 maps |
    """
    if not rows:
        return f"{what}."
    lines = ["## Skips: time saved against error added", "", f"On {what}. `x baseline` is the speed-up over the "
             "first row of the same skip, measured in the same process.", "",
             "| skip | setting | ms | x baseline | error |", "|---|---|---:|---:|---|"]
    for r in rows:
        e = r["error"]
        error = (f"median abs log(E / E_true) {e['energy']:.3f}; flicker {e['flicker_x_truth']:.2f}x the truth's; "
                 f"lag {e['lag']} frames ({e['lag_own_crops']} behind its own crops)" if r["skip"] == "video" else
                 f"L_rec-like {100 * e['l_rec_like']:.2f} % (worst map {100 * e['l_rec_like_max']:.2f} %); "
                 f"{e['lights_kept']:.1f} lights kept; {e['maps']} maps")
        lines.append(f"| {r['skip']} | {r['setting']} | {r['ms']:.2f} | {r['speedup']:.2f} | {error} |")
    return "\n".join(lines)


def format_bench(result: dict[str, Any]) -> str:
    """The Markdown report of a bench result (:func:`kornia_ilum.bench.run_bench`'s).

    Args:
        result: what :func:`~kornia_ilum.bench.run_bench` returns (or ``bench.json``): ``machine``,
            ``software``, ``error``, ``rows`` and ``auto`` are read; ``pareto``, ``per_tone``, ``e2e``,
            ``skips_what`` (with ``skips``) and ``notes`` add their sections where present.

    Returns:
        the report, ending with a newline: the machine's limits, the table of run time against error, the
        optional sections, and :data:`PAPER`'s numbers labelled as another dataset and device.

    Examples:
        >>> machine = {"cpu": "a CPU", "flags": [], "threads": 2, "fp32_gflops": 100.0, "bf16_gflops": None,
        ...            "int8_gops": 200.0, "copy_gbps": 10.0, "fresh_copy_gbps": 5.0}
        >>> result = {"machine": machine, "software": {"torch": "2.4"}, "rows": [], "auto": {},
        ...           "error": {"what": "a test", "short": "test"}}
        >>> text = format_bench(result)
        >>> text.splitlines()[0], "| bf16 matmul | not native |" in text
        ('# kornia-ilum bench', True)
    """
    m = result["machine"]
    lines = ["# kornia-ilum bench", ""]
    lines += [f"Machine: **{m['cpu']}** ({', '.join(m['flags']) or 'no SIMD flags read'}), {m['threads']} threads; "
              f"{', '.join(f'{k} {v}' for k, v in result['software'].items())}.", ""]
    peaks = [("fp32 matmul", m["fp32_gflops"], "GFLOP/s"), ("bf16 matmul", m["bf16_gflops"], "GFLOP/s"),
             ("int8 matmul", m["int8_gops"], "GOP/s"), ("copy, reused buffer", m["copy_gbps"], "GB/s"),
             ("copy, fresh memory", m["fresh_copy_gbps"], "GB/s")]
    lines += ["## The machine's limits (measured in this run)", "", "| limit | value |", "|---|---:|"]
    lines += [f"| {name} | {'not native' if v is None else f'{v:.1f} {unit}'} |" for name, v, unit in peaks]
    err = result["error"]
    lines += ["", "## Run time against error", "",
              f"Error: {err['what']}. Time: median ms per crop on {m['threads']} threads; batch 32 as crops per "
              "second; `x eager` is the speed-up over the same estimator's eager float32 row of this run; "
              "`of peak` is the GFLOP/s reached over the machine's measured matmul peak of the precision used "
              "(int8 rows against the int8 peak, though only the encoder runs in int8).", "",
              "| estimator | runtime | GFLOP/crop | b1 ms | x eager | of peak | b32 ms/crop | crops/s | x eager | "
              "of peak | L_rec diffuse | matte silver | mirror | indoor diffuse | outdoor diffuse | "
              "rel. radiance R / G / B | parity |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    front = set(result.get("pareto", []))
    for r in result["rows"]:
        lr, io = r.get("l_rec") or {}, r.get("l_rec_groups") or {}
        rr = r.get("relative_radiance")
        name = f"**{r['label']}**" if r["label"] in front else r["label"]
        speed = [_f(r.get(k), d) for k, d in (("gflop", 2), ("b1_ms_per_crop", 2), ("b1_speedup", 2),
                                             ("b1_peak_fraction", 2), ("b32_ms_per_crop", 2), ("b32_crops_per_s", 1),
                                             ("b32_speedup", 2), ("b32_peak_fraction", 2))]
        parity = r.get("parity")
        parity_text = "" if parity is None else (f"{parity['value']:.2g} (tol {parity['tolerance']:g}"
                                                 f"{', fails' if not parity['passed'] else ''})")
        lines.append(f"| {name} | {r['runtime']} | " + " | ".join(speed) + " | "
                     + " | ".join(_f(lr.get(b)) for b in ("diffuse", "matte_silver", "mirror")) + " | "
                     + " | ".join(_f((io.get(g) or {}).get("diffuse")) for g in ("indoor", "outdoor")) + " | "
                     + ("n/a" if rr is None else " / ".join(f"{v:+.3f}" for v in rr)) + f" | {parity_text} |")
    lines += ["", f"Bold: the Pareto front of batch-1 time against diffuse L_rec. `auto` picks, per estimator: "
              + ", ".join(f"{k} -> {v}" for k, v in result["auto"].items()) + "."]
    tones = result.get("per_tone")
    if tones:
        all_tones = sorted({t for v in tones.values() for t in v}, key=int)
        lines += ["", "## Diffuse L_rec per skin tone (Monk)", "",
                  "| estimator | " + " | ".join(all_tones) + " |", "|---|" + "---:|" * len(all_tones)]
        for label, per in tones.items():
            lines.append(f"| {label} | " + " | ".join(_f(per.get(t)) for t in all_tones) + " |")
    if result.get("e2e"):
        lines += ["", "## One photograph end to end (JPEG file to .exr)", "",
                  "Medians in ms. `x baseline` is the speed-up over the first row of the same photo size: the first "
                  "detector's eager path (eager float32, detection at full resolution; Haar's in the default run). "
                  "The row marked *defaults* is `kornia-ilum estimate` with no option; *+ scene* is the same with "
                  "a scene branch (`--scene`: the light's strength from the whole photo).", "",
                  "| photo | detector | detect side | runtime | read | check | detect | crop | estimate | write | "
                  "total | x baseline |", "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for e in result["e2e"]:
            stages = " | ".join(_f(e["ms"][k], 1) for k in ("read", "check", "detect", "crop", "estimate", "write",
                                                            "total"))
            runtime = f"{e['runtime']}, *defaults*" if e.get("defaults") else e["runtime"]
            runtime += ", *+ scene*" if e.get("scene") else ""
            lines.append(f"| {e['photo']} | {e['detector']} | {e['max_side'] or 'full'} | {runtime} | "
                         f"{stages} | {e['speedup']:.2f} |")
    if result.get("skips_what"):
        lines += ["", format_skips(result.get("skips") or [], result["skips_what"])]
    p = PAPER
    lines += ["", "## The paper's published numbers (another dataset, another device)", "",
              f"{p['source']}: diffuse L_rec {p['diffuse_l_rec']} on {p['dataset']}; {p['fps']} fps "
              f"({p['ms_per_frame']:.1f} ms per frame) on {p['device']}. They are printed for scale only: "
              "neither the portraits nor the machine are ours."]
    if result.get("notes"):
        lines += ["", "## Notes", ""] + [f"- {n}" for n in result["notes"]]
    return "\n".join(lines) + "\n"


def bench_figure(result: dict[str, Any], path: str | os.PathLike[str]) -> bool:
    """Draw ``bench.png`` of a bench ``result`` (as :func:`write_bench`; run time against diffuse ``L_rec``, one point
    per estimator and runtime, the Pareto front outlined) at ``path``; ``False`` without matplotlib."""
    try:
        import matplotlib  # lazy and optional: only for the figure
    except ImportError:
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as matplotlib

    rows = [r for r in result["rows"] if r.get("b1_ms_per_crop") is not None and r.get("l_rec")]
    fig, ax = plt.subplots(figsize=(8.5, 4.8), dpi=120)
    names = sorted({r["estimator"] for r in rows})
    colours = {n: plt.get_cmap("tab10")(i) for i, n in enumerate(names)}
    markers = {"eager": "o", "bf16": "s", "onnx": "^", "onnx-int8": "D", "compile": "P"}
    front = set(result.get("pareto", []))
    for r in rows:
        ax.scatter(r["b1_ms_per_crop"], r["l_rec"]["diffuse"], color=colours[r["estimator"]],
                   marker=markers.get(r["runtime"], "o"), s=70 if r["label"] in front else 35,
                   edgecolors="black" if r["label"] in front else "none", zorder=3)
        if r["runtime"] == "eager" or r["label"] in front:  # the rest: by colour and marker (the legends)
            ax.annotate(r["label"], (r["b1_ms_per_crop"], r["l_rec"]["diffuse"]), fontsize=7, xytext=(5, 4),
                        textcoords="offset points")
    ax.set_xscale("log")
    for r in result["rows"]:
        if r["runtime"] == "oracle" and r.get("l_rec"):
            ax.axhline(r["l_rec"]["diffuse"], color="grey", linestyle="--", linewidth=0.8)
            ax.text(0.01, r["l_rec"]["diffuse"], f" {r['label']}", transform=ax.get_yaxis_transform(), fontsize=7,
                    color="grey", va="bottom")
    used = sorted({r["runtime"] for r in rows}, key=list(markers).index)
    runtime_legend = ax.legend([plt.Line2D([], [], marker=markers[u], color="grey", linestyle="") for u in used],
                               used, title="runtime", fontsize=7, title_fontsize=7, loc="upper left",
                               bbox_to_anchor=(1.01, 1.0))
    ax.add_artist(runtime_legend)
    ax.legend([plt.Line2D([], [], marker="o", color=colours[n], linestyle="") for n in names], names,
              title="estimator", fontsize=7, title_fontsize=7, loc="lower left", bbox_to_anchor=(1.01, 0.0))
    ax.set_xlabel(f"ms per crop at batch 1 ({result['machine']['threads']} threads, {result['machine']['cpu']})",
                  fontsize=8)
    ax.set_ylabel("diffuse L_rec (" + result["error"]["short"] + ")", fontsize=8)
    ax.set_title("run time against error: one point per estimator x runtime (outlined: Pareto front)", fontsize=9)
    ax.grid(True, which="both", linewidth=0.3)
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)
    return True


def write_bench(result: dict[str, Any], out: str | os.PathLike[str]) -> list[Path]:
    """Write ``bench.md``, ``bench.json`` and ``bench.png`` (where matplotlib is installed) into ``out``
    (created), each atomically; returns the paths written.

    Args:
        result: a bench result, as for :func:`format_bench` (``bench.json`` is it as JSON).
        out: the folder of the three files.

    Returns:
        the paths of the files written, ``bench.png`` last (left out without matplotlib).

    Examples:
        Not run here: the figure imports matplotlib, which is slow (``tests/bench/test_report.py`` runs it).

        >>> import tempfile
        >>> machine = {"cpu": "a CPU", "flags": [], "threads": 2, "fp32_gflops": 100.0, "bf16_gflops": None,
        ...            "int8_gops": 200.0, "copy_gbps": 10.0, "fresh_copy_gbps": 5.0}
        >>> result = {"machine": machine, "software": {"torch": "2.4"}, "rows": [], "auto": {},
        ...           "error": {"what": "a test", "short": "test"}}
        >>> with tempfile.TemporaryDirectory() as tmp:  # doctest: +SKIP
        ...     [p.name for p in write_bench(result, tmp)][:2]
        ['bench.md', 'bench.json']
    """
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / "bench.md", folder / "bench.json"]
    atomic_write(written[0], lambda tmp: tmp.write_text(format_bench(result), encoding="utf-8"))
    atomic_write(written[1], lambda tmp: tmp.write_text(json.dumps(result, indent=1), encoding="utf-8"))
    if bench_figure(result, folder / "bench.png"):
        written.append(folder / "bench.png")
    return written
