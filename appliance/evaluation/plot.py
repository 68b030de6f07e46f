"""``timeline.png``: truth vs estimated TTC per track, distance, warning level over time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from appliance.config import MountConfig  # noqa: E402
from appliance.evaluation.runfiles import TrackRow, Truth, WarningRow  # noqa: E402


def plot_timeline(path: Path, truth: Truth, tracks: list[TrackRow], warnings: list[WarningRow],
                  frame_times: NDArray[np.float64], mount: MountConfig,
                  result: dict[str, Any]) -> None:
    t0 = float(frame_times[0])
    t_end = float(frame_times[-1]) - t0
    ct = truth.collision_t if truth.collision else None
    fig, (ax_ttc, ax_d, ax_w) = plt.subplots(3, 1, figsize=(10, 8), sharex=True,
                                             gridspec_kw={"height_ratios": [3, 2, 1]})
    title = f"{truth.scenario}: " + (f"collision at {ct - t0:.2f} s" if ct is not None
                                      else "no collision")
    if result.get("lead_time_s") is not None:
        title += f", level-2 lead {result['lead_time_s']:.2f} s"
    fig.suptitle(title)

    if ct is not None:
        ts = frame_times[frame_times <= ct] - t0
        ax_ttc.plot(ts, ct - t0 - ts, "k-", lw=2, label="truth TTC")
    ids = sorted({tr.id for tr in tracks})
    cmap = plt.get_cmap("tab10")
    for k, tid in enumerate(ids):
        rows = [tr for tr in tracks if tr.id == tid]
        col = cmap(k % 10)
        tt = [(r.t - t0, r.ttc_s) for r in rows if r.ttc_s is not None]
        if tt:
            a = np.array(tt)
            ax_ttc.plot(a[:, 0], a[:, 1], ".", ms=3, color=col, label=f"track {tid}")
        dd = [(r.t - t0, r.distance_m) for r in rows if r.distance_m is not None]
        if dd:
            a = np.array(dd)
            ax_d.plot(a[:, 0], a[:, 1], ".", ms=3, color=col)
    for o in truth.objects:
        if not o.moving:
            continue
        ok = np.all(np.isfinite(o.pos), axis=1) & (o.frames < len(frame_times))
        if np.any(ok):
            d = o.gap_m(np.flatnonzero(ok), mount)
            ax_d.plot(frame_times[o.frames[ok]] - t0, d, "-", color="0.3", lw=1.5,
                      label=f"truth {o.cls} {o.id}")
    ax_ttc.set_ylabel("TTC (s)")
    ax_ttc.set_ylim(0, 8)
    ax_ttc.grid(alpha=0.3)
    if ax_ttc.get_legend_handles_labels()[0]:
        ax_ttc.legend(loc="upper right", fontsize=7, ncol=2)
    ax_d.set_ylabel("distance (m)")
    ax_d.set_ylim(0, 60)
    ax_d.grid(alpha=0.3)
    if ax_d.get_legend_handles_labels()[0]:
        ax_d.legend(loc="upper right", fontsize=7)

    steps_t, steps_l = [0.0], [0]
    for w in sorted(warnings, key=lambda w: w.t):
        steps_t.append(w.t - t0)
        steps_l.append(w.level)
    steps_t.append(t_end)
    steps_l.append(steps_l[-1])
    ax_w.step(steps_t, steps_l, where="post", color="tab:red")
    ax_w.set_yticks([0, 1, 2])
    ax_w.set_ylabel("level")
    ax_w.set_xlabel("time (s)")
    ax_w.grid(alpha=0.3)
    for ax in (ax_ttc, ax_d, ax_w):
        if ct is not None:
            ax.axvline(ct - t0, color="k", ls="--", lw=1)
        ax.set_xlim(0, max(t_end, 1e-3))
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
