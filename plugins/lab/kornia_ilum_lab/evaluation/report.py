r"""The evaluation's tables: summaries of the per-sample scores, as Markdown and JSON.

- **Table 1**: ``L_rec`` per reference sphere (diffuse, matte silver, mirror) for the indoor, outdoor and all
  samples: means over samples (lower is better).
- **Table 2**: relative radiance per channel, ``(sum L_gt - sum L_pred) / sum L_gt`` (solid-angle weighted):
  mean (the bias; negative: too much light) and mean absolute value.
- **Table 3**: per skin tone (the subject's Monk tone): ``L_rec`` per sphere, with its 95 % interval over
  subjects (:mod:`~kornia_ilum_lab.evaluation.bootstrap`), and the mean relative radiance per channel.
- **Paired differences** against a reference method (``ours`` by default, where it was scored): per sphere, the
  mean over samples of ``L_rec(method) - L_rec(reference)`` on the same portraits, its 95 % interval (normal
  approximation, ``1.96`` standard errors of the mean) and the fraction of samples where the method is better.
  The means of Table 1 can differ by less than their noise; this says whether an ordering holds.
- **Checks** (:mod:`~kornia_ilum_lab.evaluation.checks`, where they were run): the label-free transfer check
  (medians per skin tone of the estimated energy with the background, over black and over grey, against each
  other and the truth), exposure equivariance (``E(k x) / (k E(x))`` on the eval crops and on real photos) and
  crop stability (the spread of the estimate over jittered crops, medians over portraits per skin tone).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import torch

from kornia_ilum_lab.evaluation.bootstrap import subject_interval
from kornia_ilum_lab.evaluation.colour import colour_markdown
from kornia_ilum_lab.evaluation.evaluate import BRDF_NAMES, EvalSet
from kornia_ilum_lab.evaluation.flash import flash_markdown
from kornia_ilum_lab.evaluation.rule import rule_markdown

__all__ = ["format_markdown", "paired_differences", "summarize", "write_report"]

_GROUPS = ("indoor", "outdoor", "all")
_CHANNELS = ("r", "g", "b")


def _mean(x: torch.Tensor) -> float | None:
    return None if x.numel() == 0 else float(x.double().mean())


def _means(x: torch.Tensor) -> list[float] | None:
    return None if x.numel() == 0 else [float(v) for v in x.double().mean(0)]


def paired_differences(scores: dict[str, torch.Tensor], reference: dict[str, torch.Tensor]
                       ) -> dict[str, dict[str, float]]:
    r"""Per sphere, ``L_rec(method) - L_rec(reference)`` on the same portraits (module docstring, "Paired
    differences"): ``mean``, its 95 % interval ``low`` and ``high``, and ``better``, the fraction of samples
    where the method is better.

    Args:
        scores, reference: per-sample scores of :func:`~kornia_ilum_lab.evaluation.score` on one eval set.

    Returns:
        ``{sphere: {"mean", "low", "high", "better"}}`` for the three spheres, floats; ``low`` and ``high`` are
        NaN with a single sample.

    Shape:
        - scores[sphere], reference[sphere]: :math:`(N,)`, the same portraits in the same order

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec": lower is better, so a negative ``mean`` favours
        the method.

    Examples:
        >>> ref = {b: torch.tensor([0.2, 0.3]) for b in BRDF_NAMES}
        >>> mine = {b: torch.tensor([0.1, 0.3]) for b in BRDF_NAMES}
        >>> d = paired_differences(mine, ref)["diffuse"]
        >>> round(d["mean"], 6), d["better"]
        (-0.05, 0.5)
    """
    out = {}
    for b in BRDF_NAMES:
        d = (scores[b] - reference[b]).double()
        half = 1.96 * float(d.std()) / len(d) ** 0.5 if len(d) > 1 else math.nan
        mean = float(d.mean())
        out[b] = {"mean": mean, "low": mean - half, "high": mean + half, "better": float((d < 0).double().mean())}
    return out


def summarize(results: dict[str, Any], eval_set: EvalSet, reference: str = "ours") -> dict[str, Any]:
    r"""The tables as a JSON-ready dict.

    Args:
        results: from :func:`~kornia_ilum_lab.evaluation.evaluate` (with ``"checks"``, the checks' settings, where
            the caller added them).
        eval_set: the set that was scored.
        reference: the method of the paired differences (none where it was not scored).

    Returns:
        a dict with the keys ``eval_set`` (the set's description), ``skipped`` (name to reason),
        ``seconds`` (name to seconds), ``table1_l_rec`` (method, group, brdf to the mean),
        ``table2_relative_radiance`` (method, group to ``mean`` and ``mean_abs``, each ``[r, g, b]``) and
        ``per_skin_tone`` (method, tone to ``count``, the mean per brdf, ``relative_radiance`` and
        ``relative_radiance_abs``); the groups are ``indoor``, ``outdoor`` and ``all`` (a group without
        samples holds ``None``); ``paired`` (``reference`` and, per other method and brdf, ``mean``, ``low``,
        ``high`` and ``better``: the module docstring); where methods were scored from weight files
        (``--weights``), ``weights`` (method to the file's SHA-256); and where checks were run,
        ``checks`` (method to the tables of :func:`~kornia_ilum_lab.evaluation.checks.run_checks`) and
        ``check_settings`` (the checks, their options, the number of real photos, the context set's
        description).

    Examples:
        >>> from kornia_ilum_lab.evaluation import score
        >>> gt = torch.ones(2, 3, 32, 32)
        >>> eval_set = EvalSet(torch.zeros(2, 3, 8, 8, dtype=torch.uint8), gt, ["indoor", "outdoor"], [3, 7],
        ...                    [0, 1], ["room", "sky"])
        >>> results = {"methods": {"ours": {"scores": score(gt, gt), "seconds": 1.0},
        ...                        "half": {"scores": score(gt / 2, gt), "seconds": 1.0}}, "skipped": {}}
        >>> summary = summarize(results, eval_set)
        >>> summary["table1_l_rec"]["ours"]["all"]["diffuse"], summary["paired"]["reference"]
        (0.0, 'ours')
        >>> [round(v, 4) for v in summary["table2_relative_radiance"]["half"]["indoor"]["mean"]]
        [0.5, 0.5, 0.5]
    """
    labels = eval_set.label
    masks = {g: torch.tensor([g == "all" or lab == g for lab in labels], dtype=torch.bool) for g in _GROUPS}
    tones = torch.tensor(eval_set.skin_tone)
    subjects = torch.tensor(eval_set.subject_seed)
    t1: dict[str, Any] = {}
    t2: dict[str, Any] = {}
    t3: dict[str, Any] = {}
    for name, method in results["methods"].items():
        s = method["scores"]
        rr = s["relative_radiance"]
        t1[name] = {g: {b: _mean(s[b][m]) for b in BRDF_NAMES} for g, m in masks.items()}
        t2[name] = {g: {"mean": _means(rr[m]), "mean_abs": _means(rr[m].abs())} for g, m in masks.items()}
        t3[name] = {}
        for tone in sorted(set(eval_set.skin_tone)):
            m = tones == tone
            t3[name][str(tone)] = {"count": int(m.sum()), "subjects": len(set(subjects[m].tolist())),
                                   **{b: _mean(s[b][m]) for b in BRDF_NAMES},
                                   **{f"{b}_ci": subject_interval(s[b][m], subjects[m], statistic=torch.mean)
                                      for b in BRDF_NAMES},
                                   "relative_radiance": _means(rr[m]), "relative_radiance_abs": _means(rr[m].abs())}
    digests = {n: m["sha256"] for n, m in results["methods"].items() if "sha256" in m}
    checks = {n: m["checks"] for n, m in results["methods"].items() if "checks" in m}
    extra = {"checks": checks, "check_settings": results.get("checks", {})} if checks else {}
    return {
        "eval_set": eval_set.description,
        "skipped": dict(results["skipped"]),
        "seconds": {n: m["seconds"] for n, m in results["methods"].items()},
        **({"weights": digests} if digests else {}),
        "table1_l_rec": t1,
        "table2_relative_radiance": t2,
        "per_skin_tone": t3,
        "paired": {"reference": reference if reference in results["methods"] else None,
                   "methods": {name: paired_differences(m["scores"], results["methods"][reference]["scores"])
                               for name, m in results["methods"].items() if name != reference}
                   if reference in results["methods"] else {}},
        **extra,
    }


def _f(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _rgb(x: list[float] | None) -> str:
    return "-" if x is None else " / ".join(f"{v:+.3f}" for v in x)


def format_markdown(summary: dict[str, Any]) -> str:
    r"""The tables of :func:`summarize` as Markdown (with a line on the eval set, the skipped estimators and
    the SHA-256 of the weight files scored).

    Args:
        summary: from :func:`summarize` (or read back from its JSON).

    Returns:
        the Markdown text, ending in a newline: Table 1, Table 2, the skin-tone table, and where the summary has
        them the paired differences, the checks' tables, the shipping rule's verdicts, the skipped methods, the weight files and the held-out
        maps.

    Examples:
        >>> from kornia_ilum_lab.evaluation import score
        >>> gt = torch.ones(2, 3, 32, 32)
        >>> eval_set = EvalSet(torch.zeros(2, 3, 8, 8, dtype=torch.uint8), gt, ["indoor", "outdoor"], [3, 7],
        ...                    [0, 1], ["room", "sky"])
        >>> results = {"methods": {"ours": {"scores": score(gt, gt), "seconds": 1.0}},
        ...            "skipped": {"sipr": "no weights"}}
        >>> text = format_markdown(summarize(results, eval_set))
        >>> text.splitlines()[0], "| ours | 0.0000 |" in text, "- sipr: no weights" in text
        ('# Held-out evaluation', True, True)
    """
    d = summary["eval_set"]
    lab = d.get("labels", {})
    n_maps = sum(len(v) for v in d.get("eval_maps", {}).values())
    lines = [
        "# Held-out evaluation",
        "",
        (f"{d.get('samples')} portraits ({lab.get('indoor', 0)} indoor, {lab.get('outdoor', 0)} outdoor) of "
         f"{len(d.get('subjects', []))} eval subjects ({d.get('fields')} views), seed {d.get('seed')}; "
         f"environments: {', '.join(f'{k} {v}' for k, v in d.get('sources', {}).items())} "
         f"({n_maps} held-out real maps); background: {d.get('background', 'environment')}."),
        "",
        "## Table 1: L_rec (lower is better), mean over samples",
        "",
        "| method | " + " | ".join(f"{g} {b}" for g in _GROUPS for b in BRDF_NAMES) + " |",
        "|---|" + "---:|" * (len(_GROUPS) * len(BRDF_NAMES)),
    ]
    for name, groups in summary["table1_l_rec"].items():
        lines.append(f"| {name} | " + " | ".join(_f(groups[g][b]) for g in _GROUPS for b in BRDF_NAMES) + " |")
    lines += [
        "",
        "## Table 2: relative radiance (sum L_gt - sum L_pred) / sum L_gt, R / G / B",
        "",
        "| method | " + " | ".join(f"{g} mean | {g} mean abs" for g in _GROUPS) + " |",
        "|---|" + "---:|" * (2 * len(_GROUPS)),
    ]
    for name, groups in summary["table2_relative_radiance"].items():
        cells = [c for g in _GROUPS for c in (_rgb(groups[g]["mean"]), _rgb(groups[g]["mean_abs"]))]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Per skin tone (Monk scale): L_rec [95 % interval over subjects] and relative radiance (mean, R / G / B)",
        "",
        "| method | tone | samples | subjects | " + " | ".join(BRDF_NAMES) + " | relative radiance | mean abs |",
        "|---|---:|---:|---:|" + "---:|" * (len(BRDF_NAMES) + 2),
    ]
    for name, tones in summary["per_skin_tone"].items():
        for tone, row in tones.items():
            lines.append(f"| {name} | {tone} | {row['count']} | {row.get('subjects', '-')} | "
                         + " | ".join(_f(row[b]) + _interval(row.get(f"{b}_ci"), 4) for b in BRDF_NAMES)
                         + f" | {_rgb(row['relative_radiance'])} | {_rgb(row['relative_radiance_abs'])} |")
    paired = summary.get("paired", {})
    if paired.get("methods"):
        ref = paired["reference"]
        lines += [
            "",
            f"## Paired differences: L_rec(method) - L_rec({ref}) on the same portraits, mean [95 % interval], "
            f"and the samples where the method is better",
            "",
            "| method | " + " | ".join(BRDF_NAMES) + " |",
            "|---|" + "---:|" * len(BRDF_NAMES),
        ]
        for name, rows in paired["methods"].items():
            cells = [f"{r['mean']:+.4f} [{r['low']:+.4f}, {r['high']:+.4f}], {100 * r['better']:.1f} %"
                     for r in (rows[b] for b in BRDF_NAMES)]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += _check_tables(summary)
    lines += rule_markdown(summary.get("rule") or [])
    if summary["skipped"]:
        lines += ["", "Skipped:"] + [f"- {n}: {' '.join(r.split())}" for n, r in summary["skipped"].items()]
    if summary.get("weights"):
        lines += ["", "Weight files:"] + [f"- {n}: sha256 {h}" for n, h in summary["weights"].items()]
    if d.get("eval_maps"):
        lines += ["", "Held-out real maps:"]
        for folder, maps in d["eval_maps"].items():
            lines.append(f"- {folder}: " + ", ".join(f"{n} ({v})" for n, v in maps.items()))
    return "\n".join(lines) + "\n"


def _interval(ci: list[float] | None, digits: int = 3) -> str:
    if not ci or any(v is None or math.isnan(v) for v in ci):
        return ""
    return f" [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"


def _cell(row: dict[str, Any] | None) -> str:
    if not row or row.get("median") is None:
        return "-"
    return f"{row['median']:.3f} [{row['q25']:.3f}, {row['q75']:.3f}]"


def _check_tables(summary: dict[str, Any]) -> list[str]:
    """The Markdown tables of the checks (none where none was run)."""
    checks = summary.get("checks") or {}
    lines: list[str] = []
    transfer = {n: c["transfer"] for n, c in checks.items() if "transfer" in c}
    if transfer:
        keys = ("with/true", "black/true", "grey/true", "black/with", "grey/with")
        lines += [
            "",
            "## Transfer check: estimated energy with the background, over black and over grey (sRGB 0.5), "
            "and the truth; medians of the ratios",
            "",
            "| method | tone | samples | " + " | ".join(f"E {k}" for k in keys) + " |",
            "|---|---:|---:|" + "---:|" * len(keys),
        ]
        for name, groups in transfer.items():
            for tone, row in groups.items():
                cells = " | ".join(_f(row[k], 3) + _interval(row.get(f"{k}_ci")) for k in keys)
                lines.append(f"| {name} | {tone} | {row['count']} | {cells} |")
        spreads = {n: c["tone_spread"] for n, c in checks.items() if c.get("tone_spread")}
        if spreads:
            lines += ["", "Across skin tones, the largest over the smallest per-tone median [95 % interval over "
                      "subjects] (tones):", ""]
            for name, ratios in spreads.items():
                lines.append(f"- {name}: " + "; ".join(
                    f"E {k} {r['ratio']:.2f}{_interval(r['interval'], 2)} ({r['max']} over {r['min']})"
                    for k, r in ratios.items()))
    exposure = {n: c["exposure"] for n, c in checks.items() if "exposure" in c}
    if exposure:
        ks = list(next(iter(exposure.values()))["eval"])
        lines += [
            "",
            "## Exposure equivariance: E(k x) / (k E(x)), k in linear light without new clipping; median "
            "[quartiles] (1: the estimate scales with the photo)",
            "",
            "| method | photos | count | " + " | ".join(f"k = {k}" for k in ks) + " |",
            "|---|---|---:|" + "---:|" * len(ks),
        ]
        for name, sets in exposure.items():
            for which, table in sets.items():
                count = max((row["count"] for row in table.values()), default=0)
                label = "eval crops" if which == "eval" else "real photos"
                cells = " | ".join(_cell(table.get(k)) for k in ks)
                lines.append(f"| {name} | {label} | {count} | {cells} |")
    crop = {n: c["crop"] for n, c in checks.items() if "crop" in c}
    if crop:
        s = summary.get("check_settings", {})
        how = (f"{s.get('jitters', 8)} crops per portrait, centre moved by up to "
               f"{100 * s.get('position', 0.10):.0f} % of the side, side times "
               f"e^(+-{s.get('extent', 0.15):g})")
        lines += [
            "",
            f"## Crop stability: {how}; medians over portraits",
            "",
            "| method | tone | portraits | std log E | max / min E | angle to the mean direction (deg) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for name, groups in crop.items():
            for tone, row in groups.items():
                lines.append(f"| {name} | {tone} | {row['count']} | {_f(row['std_log_energy'], 3)} | "
                             f"{_f(row['max_min_ratio'], 3)} | {_f(row['angle_deg'], 2)} |")
    spread = {n: c["spread"] for n, c in checks.items() if "spread" in c}
    if spread:
        lines += [
            "",
            "## Spread of the log energy: the share of portraits whose true log energy lies within +-1 and +-2 "
            "spreads of the estimate's [95 % interval over subjects]; calibrated: 0.632 and 0.865",
            "",
            "| method | tone | samples | median spread | within 1 | within 2 |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for name, result in spread.items():
            if result["table"] is None:
                lines.append(f"| {name} | - | - | {result['reason']} | - | - |")
                continue
            for tone, row in result["table"].items():
                lines.append(f"| {name} | {tone} | {row['count']} | {_f(row['spread'], 3)} | "
                             f"{_f(row['within_1'], 3)}{_interval(row['within_1_ci'])} | "
                             f"{_f(row['within_2'], 3)}{_interval(row['within_2_ci'])} |")
    lines += colour_markdown({n: c["colour"] for n, c in checks.items() if "colour" in c})
    lines += flash_markdown({n: c["flash"] for n, c in checks.items() if "flash" in c})
    if checks:
        spent = ("; ".join(f"{n}: " + ", ".join(f"{k} {v:.1f}" for k, v in c.get("seconds", {}).items())
                           for n, c in checks.items()))
        lines += ["", f"Checks' seconds: {spent}"]
    return lines


def write_report(summary: dict[str, Any], markdown: str | os.PathLike[str] | None = None,
                 json_path: str | os.PathLike[str] | None = None, *, text: str | None = None) -> list[Path]:
    """Write the Markdown and / or JSON files (parents created); returns the paths written.

    Args:
        summary: from :func:`summarize`.
        markdown: where to write :func:`format_markdown`'s text (or ``text``); ``None`` writes none.
        text: the Markdown to write instead of :func:`format_markdown`'s (a report of another shape).
        json_path: where to write ``summary`` as JSON; ``None`` writes none.

    Returns:
        the paths written, Markdown first.

    Examples:
        >>> import tempfile
        >>> summary = {"eval_set": {}, "skipped": {}, "table1_l_rec": {}, "table2_relative_radiance": {},
        ...            "per_skin_tone": {}}
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     written = write_report(summary, Path(tmp, "eval", "evaluation.md"), Path(tmp, "evaluation.json"))
        ...     back = json.loads(written[1].read_text())
        >>> [p.name for p in written], back == summary
        (['evaluation.md', 'evaluation.json'], True)
    """
    written = []
    if markdown is not None:
        path = Path(markdown)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(format_markdown(summary) if text is None else text)
        written.append(path)
    if json_path is not None:
        path = Path(json_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(summary, indent=1, sort_keys=False) + "\n")
        written.append(path)
    return written
