r"""
Choose an estimator and a runtime by speed and error
====================================================

``kornia-ilum bench`` measures every estimator under every runtime on the machine at hand: milliseconds per
crop against ``L_rec`` on the held-out light-stage portraits. Its JSON (``bench.json``) holds the rows; the
docs keep the run of :doc:`/bench`. Here we read that file, draw the trade-off and pick, for a time budget,
the most accurate choice that fits.
"""

import json
from pathlib import Path

import matplotlib.pyplot as plt

here = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()
result = json.loads((here.parent / "_static" / "bench" / "bench.json").read_text())
rows = [r for r in result["rows"] if r.get("b1_ms_per_crop") is not None and r.get("l_rec")]
for r in sorted(rows, key=lambda r: r["b1_ms_per_crop"]):
    print(f"{r['label']:18s} {r['b1_ms_per_crop']:7.2f} ms  diffuse L_rec {r['l_rec']['diffuse']:.4f}")

# %%
# The most accurate within a budget
# ---------------------------------
# ``runtime="auto"`` makes this choice per estimator at run time (the fastest runtime that passes its parity
# check); across estimators the choice is yours.

budget_ms = 8.0
fits = [r for r in rows if r["b1_ms_per_crop"] <= budget_ms]
best = min(fits, key=lambda r: r["l_rec"]["diffuse"])
print(f"within {budget_ms} ms: {best['label']} ({best['b1_ms_per_crop']:.2f} ms, {best['l_rec']['diffuse']:.4f})")

fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
for r in rows:
    ax.scatter(r["b1_ms_per_crop"], r["l_rec"]["diffuse"], color="C1" if r is best else "C0")
    ax.annotate(r["label"], (r["b1_ms_per_crop"], r["l_rec"]["diffuse"]), fontsize=7, xytext=(3, 2),
                textcoords="offset points")
ax.axvline(budget_ms, color="grey", lw=0.8, ls="--")
ax.set_xscale("log")
ax.set_xlabel("ms per crop, batch 1")
ax.set_ylabel("diffuse L_rec (held-out)")
plt.show()
