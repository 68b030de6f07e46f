"""``batch.png``: the distributions of lead time and TTC error over a batch's evaluated runs."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt

from appliance.evaluation.metrics import TARGETS


def plot_batch(path: Path, evaluations: Sequence[dict[str, Any]]) -> None:
    """Lead time of the collision runs (missed warnings counted apart) and each run's median
    relative TTC error in the last 3 s, with the targets."""
    coll = [e for e in evaluations if "error" not in e and e["collision"]]
    leads = [e["lead_time_s"] for e in coll if e["lead_time_s"] is not None]
    missed = len(coll) - len(leads)
    ttc = [100.0 * e["ttc_rel_error_median"] for e in coll
           if e["ttc_rel_error_median"] is not None]
    fig, (ax_lead, ax_ttc) = plt.subplots(1, 2, figsize=(11, 4))
    ax_lead.hist(leads, bins=20, color="tab:blue")
    ax_lead.axvline(TARGETS["lead_time_s"], color="tab:red", ls="--",
                    label=f"target {TARGETS['lead_time_s']:.1f} s")
    ax_lead.set_xlabel("lead time of the first level-2 warning, s")
    ax_lead.set_ylabel("collision runs")
    ax_lead.set_title(f"lead time: {len(leads)} warned, {missed} missed")
    ax_lead.legend()
    ax_ttc.hist(ttc, bins=20, color="tab:green")
    ax_ttc.axvline(100.0 * TARGETS["ttc_rel_error"], color="tab:red", ls="--",
                   label=f"target {100.0 * TARGETS['ttc_rel_error']:.0f} %")
    ax_ttc.set_xlabel("median |TTC error| / TTC in the last 3 s, %")
    ax_ttc.set_ylabel("collision runs")
    ax_ttc.set_title(f"TTC error: {len(ttc)} runs with a TTC")
    ax_ttc.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
