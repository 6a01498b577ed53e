r"""The shipping rule: whether a candidate's weights may replace the shipped ones, read from one evaluation.

A model ships only if, scored in the same ``kornia-ilum evaluate`` run as the shipped weights of its estimator
(docs/training.rst, "The shipping rule"):

1. ``L_rec`` (all eval portraits) is within 3 % of the shipped model's for the diffuse and matte silver spheres
   and within 10 % for the mirror sphere (issue 39's limits);
2. the tone spread of ``E with / true`` (the largest over the smallest per-tone median, the transfer check) is
   no larger than the shipped model's (issue 39: per-tone energy first);
3. on the real-flash photographs, the main light's median direction error over all flashes and within 25
   degrees of the camera axis is not worse than the shipped model's, and the left/right sign agreement not
   lower: "not worse" is the candidate's median inside or below the shipped model's 95 % interval over people
   (the interval says what the people drawn could have given by chance);
4. under the colour check on the eval portraits, the median angle the main light turns is not worse than the
   shipped model's for any look, in the same sense (95 % interval over subjects).

A clause whose check was not run fails: a model is not shipped on what was not measured.
"""

from __future__ import annotations

from typing import Any

__all__ = ["LREC_LIMITS", "rule_markdown", "shipping_rule"]

#: The largest relative increase of each sphere's mean ``L_rec`` over the shipped model's.
LREC_LIMITS: dict[str, float] = {"diffuse": 0.03, "matte_silver": 0.03, "mirror": 0.10}


def _clause(name: str, candidate: float | None, reference: float | None, passed: bool | None,
            bound: str) -> dict[str, Any]:
    return {"clause": name, "candidate": candidate, "reference": reference, "bound": bound,
            "pass": bool(passed) if passed is not None else False, "measured": passed is not None}


def _not_worse(candidate: dict[str, Any] | None, reference: dict[str, Any] | None, *, lower_is_better: bool = True,
               key: str = "median", ci: str = "ci") -> tuple[float | None, float | None, bool | None, str]:
    """The candidate's value against the shipped one's 95 % interval (module docstring)."""
    if not candidate or not reference or candidate.get(key) is None or reference.get(key) is None:
        return None, None, None, "not measured"
    c, r = float(candidate[key]), float(reference[key])
    interval = reference.get(ci) or [r, r]
    if lower_is_better:
        return c, r, c <= interval[1], f"<= {interval[1]:.3g}"
    return c, r, c >= interval[0], f">= {interval[0]:.3g}"


def shipping_rule(summary: dict[str, Any], candidate: str, reference: str) -> dict[str, Any]:
    r"""Each clause of the rule (module docstring) for ``candidate`` against ``reference``, and the verdict.

    Args:
        summary: the JSON summary of one ``kornia-ilum evaluate`` run that scored both
            (:func:`~kornia_ilum_lab.evaluation.report.summarize`), with the checks ``transfer``, ``colour`` and
            ``flash``.
        candidate, reference: the two methods' names in it (``"ours@run.safetensors"``, ``"ours"``).

    Returns:
        a dict of ``"candidate"``, ``"reference"``, ``"ships"`` (bool) and ``"clauses"``, a list of dicts with
        ``"clause"``, ``"candidate"``, ``"reference"``, ``"bound"``, ``"pass"`` and ``"measured"``.

    Raises:
        KeyError: a method that the summary did not score.

    Examples:
        >>> table = {m: {"all": {"diffuse": d, "matte_silver": 0.1, "mirror": 0.2}}
        ...          for m, d in (("new", 0.090), ("old", 0.088))}
        >>> verdict = shipping_rule({"table1_l_rec": table}, "new", "old")
        >>> verdict["clauses"][0]["pass"], verdict["ships"]  # L_rec within 3 %, but the checks were not run
        (True, False)
    """
    t1 = summary["table1_l_rec"]
    c_scores, r_scores = t1[candidate]["all"], t1[reference]["all"]
    clauses = []
    for brdf, limit in LREC_LIMITS.items():
        c, r = c_scores[brdf], r_scores[brdf]
        passed = None if c is None or r is None else c <= r * (1.0 + limit)
        clauses.append(_clause(f"L_rec {brdf} within +{100 * limit:.0f} %", c, r, passed,
                               "not measured" if r is None else f"<= {r * (1.0 + limit):.4f}"))
    checks = summary.get("checks", {})
    c_checks, r_checks = checks.get(candidate, {}), checks.get(reference, {})

    def spread(which: dict[str, Any]) -> float | None:
        ratio = (which.get("tone_spread") or {}).get("with/true") or {}
        return ratio.get("ratio")

    c, r = spread(c_checks), spread(r_checks)
    clauses.append(_clause("tone spread of E with / true not larger", c, r,
                           None if c is None or r is None else c <= r, "not measured" if r is None else f"<= {r:.3g}"))
    c_flash, r_flash = c_checks.get("flash") or {}, r_checks.get("flash") or {}
    for band in ("all", "within 25"):
        c, r, passed, bound = _not_worse((c_flash.get("direction") or {}).get(band),
                                         (r_flash.get("direction") or {}).get(band))
        clauses.append(_clause(f"real flash: direction error, {band} (deg)", c, r, passed, bound))
    c, r, passed, bound = _not_worse(c_flash.get("left_right"), r_flash.get("left_right"), lower_is_better=False,
                                     key="rate")
    clauses.append(_clause("real flash: left/right agreement", c, r, passed, bound))
    c_colour = (c_checks.get("colour") or {}).get("eval") or {}
    r_colour = (r_checks.get("colour") or {}).get("eval") or {}
    for look in r_colour or ("greyscale",):
        c_row, r_row = c_colour.get(look), r_colour.get(look)
        c, r, passed, bound = _not_worse(c_row and c_row["angle"], r_row and {**r_row["angle"],
                                                                               "ci": r_row.get("angle_ci")})
        clauses.append(_clause(f"colour check: {look}, angle (deg)", c, r, passed, bound))
    return {"candidate": candidate, "reference": reference, "clauses": clauses,
            "ships": all(c["pass"] for c in clauses)}


def rule_markdown(verdicts: list[dict[str, Any]]) -> list[str]:
    r"""The rule's Markdown table: one row per clause, per candidate.

    Args:
        verdicts: from :func:`shipping_rule`.

    Returns:
        the lines (none for no verdict).
    """
    if not verdicts:
        return []
    lines = ["", "## The shipping rule (docs/training.rst): each candidate against the shipped weights", "",
             "| candidate | clause | candidate | shipped | bound | pass |", "|---|---|---:|---:|---:|---|"]

    def number(x: float | None) -> str:
        return "-" if x is None else f"{x:.4g}"

    for v in verdicts:
        for c in v["clauses"]:
            lines.append(f"| {v['candidate']} | {c['clause']} | {number(c['candidate'])} | {number(c['reference'])} "
                         f"| {c['bound']} | {'yes' if c['pass'] else 'no'} |")
        lines.append(f"| {v['candidate']} | **ships** | | | | **{'yes' if v['ships'] else 'no'}** |")
    return lines
