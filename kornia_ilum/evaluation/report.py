r"""The evaluation's tables: summaries of the per-sample scores, as Markdown and JSON.

- **Table 1**: ``L_rec`` per reference sphere (diffuse, matte silver, mirror) for the indoor, outdoor and all
  samples: means over samples (lower is better).
- **Table 2**: relative radiance per channel, ``(sum L_gt - sum L_pred) / sum L_gt`` (solid-angle weighted):
  mean (the bias; negative: too much light) and mean absolute value.
- **Table 3**: per skin tone (the subject's Monk tone): ``L_rec`` per sphere and the mean relative radiance per
  channel.
- **Paired differences** against a reference method (``ours`` by default, where it was scored): per sphere, the
  mean over samples of ``L_rec(method) - L_rec(reference)`` on the same portraits, its 95 % interval (normal
  approximation, ``1.96`` standard errors of the mean) and the fraction of samples where the method is better.
  The means of Table 1 can differ by less than their noise; this says whether an ordering holds.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import torch

from kornia_ilum.evaluation.evaluate import BRDF_NAMES, EvalSet

__all__ = ["format_markdown", "summarize", "write_report"]

_GROUPS = ("indoor", "outdoor", "all")
_CHANNELS = ("r", "g", "b")


def _mean(x: torch.Tensor) -> float | None:
    return None if x.numel() == 0 else float(x.double().mean())


def _means(x: torch.Tensor) -> list[float] | None:
    return None if x.numel() == 0 else [float(v) for v in x.double().mean(0)]


def _paired(scores: dict[str, torch.Tensor], reference: dict[str, torch.Tensor]) -> dict[str, dict[str, float]]:
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
        results: from :func:`~kornia_ilum.evaluation.evaluate`.
        eval_set: the set that was scored.
        reference: the method of the paired differences (none where it was not scored).

    Returns:
        a dict with the keys ``eval_set`` (the set's description), ``skipped`` (name to reason),
        ``seconds`` (name to seconds), ``table1_l_rec`` (method, group, brdf to the mean),
        ``table2_relative_radiance`` (method, group to ``mean`` and ``mean_abs``, each ``[r, g, b]``) and
        ``per_skin_tone`` (method, tone to ``count``, the mean per brdf, ``relative_radiance`` and
        ``relative_radiance_abs``); the groups are ``indoor``, ``outdoor`` and ``all`` (a group without
        samples holds ``None``); ``paired`` (``reference`` and, per other method and brdf, ``mean``, ``low``,
        ``high`` and ``better``: the module docstring); and, where methods were scored from weight files
        (``--weights``), ``weights`` (method to the file's SHA-256).
    """
    labels = eval_set.label
    masks = {g: torch.tensor([g == "all" or lab == g for lab in labels], dtype=torch.bool) for g in _GROUPS}
    tones = torch.tensor(eval_set.skin_tone)
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
            t3[name][str(tone)] = {"count": int(m.sum()), **{b: _mean(s[b][m]) for b in BRDF_NAMES},
                                   "relative_radiance": _means(rr[m]), "relative_radiance_abs": _means(rr[m].abs())}
    digests = {n: m["sha256"] for n, m in results["methods"].items() if "sha256" in m}
    return {
        "eval_set": eval_set.description,
        "skipped": dict(results["skipped"]),
        "seconds": {n: m["seconds"] for n, m in results["methods"].items()},
        **({"weights": digests} if digests else {}),
        "table1_l_rec": t1,
        "table2_relative_radiance": t2,
        "per_skin_tone": t3,
        "paired": {"reference": reference if reference in results["methods"] else None,
                   "methods": {name: _paired(m["scores"], results["methods"][reference]["scores"])
                               for name, m in results["methods"].items() if name != reference}
                   if reference in results["methods"] else {}},
    }


def _f(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _rgb(x: list[float] | None) -> str:
    return "-" if x is None else " / ".join(f"{v:+.3f}" for v in x)


def format_markdown(summary: dict[str, Any]) -> str:
    r"""The tables of :func:`summarize` as Markdown (with a line on the eval set, the skipped estimators and
    the SHA-256 of the weight files scored)."""
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
        "## Per skin tone (Monk scale): L_rec and relative radiance (mean, R / G / B)",
        "",
        "| method | tone | samples | " + " | ".join(BRDF_NAMES) + " | relative radiance | mean abs |",
        "|---|---:|---:|" + "---:|" * (len(BRDF_NAMES) + 2),
    ]
    for name, tones in summary["per_skin_tone"].items():
        for tone, row in tones.items():
            lines.append(f"| {name} | {tone} | {row['count']} | " + " | ".join(_f(row[b]) for b in BRDF_NAMES)
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
    if summary["skipped"]:
        lines += ["", "Skipped:"] + [f"- {n}: {' '.join(r.split())}" for n, r in summary["skipped"].items()]
    if summary.get("weights"):
        lines += ["", "Weight files:"] + [f"- {n}: sha256 {h}" for n, h in summary["weights"].items()]
    if d.get("eval_maps"):
        lines += ["", "Held-out real maps:"]
        for folder, maps in d["eval_maps"].items():
            lines.append(f"- {folder}: " + ", ".join(f"{n} ({v})" for n, v in maps.items()))
    return "\n".join(lines) + "\n"


def write_report(summary: dict[str, Any], markdown: str | os.PathLike[str] | None = None,
                 json_path: str | os.PathLike[str] | None = None) -> list[Path]:
    """Write the Markdown and / or JSON files (parents created); returns the paths written."""
    written = []
    if markdown is not None:
        path = Path(markdown)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(format_markdown(summary))
        written.append(path)
    if json_path is not None:
        path = Path(json_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(summary, indent=1, sort_keys=False) + "\n")
        written.append(path)
    return written
