"""The kitti-street world's generator with cars that stand or brake in the ego lane.

Run in the world's interpreter: ``python _kitti_street_standing.py WORLD [generate.py
options]``. The world takes further mover kinds through its ``scenarios.HOLDOUT_MOVERS``
hook (a function of the scenario, its random generator and its speed jitter, returning a
``Mover``); this registers three, with a scenario each beside the world's own, and hands the
rest of the command line to the world's ``generate.py``. Nothing of the world is copied: its
path, ego motion, street, renderer, truth and collision test are its own.

* ``car_stopped_k00``: a car standing in the ego lane, on the KITTI 00 segment (about
  33 km/h), where the ego's front reaches it at the scenario's conflict time;
* ``car_stopped_k06``: the same on KITTI 06 (about 42 km/h);
* ``lead_braking_k06``: a lead car 15 m (x the speed jitter) ahead in the ego lane, at the
  ego's speed, brakes at 4 m/s^2 (x the jitter) to a standstill, timed so that the ego, which
  does not brake, reaches it at the conflict time;
* ``car_stopped_next_lane_k06``: no collision, a car standing 3.2 m to the left of the ego
  path.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np


def register(S: Any) -> None:
    """Add the movers and scenarios to the world's ``scenarios`` module ``S``."""
    car_l = S.DIMS["car"][0]

    def stopped(lateral: float) -> Callable[[Any, Any, float], Any]:
        def make(sc: Any, rng: Any, jv: float) -> Any:
            s_stop = float(sc.path.s_of_t(sc.t_conflict)) + S.VEH_FRONT + car_l / 2
            return S.Mover(1, "car", S.PathMotion(
                sc.path, lambda t: s_stop + 0.0 * np.asarray(t), lateral), rng)
        return make

    def braking(decel: float, gap0: float) -> Callable[[Any, Any, float], Any]:
        def make(sc: Any, rng: Any, jv: float) -> Any:
            gap, a = gap0 * jv + S.VEH_FRONT + car_l / 2, decel * jv
            grid = np.arange(0.0, S.DURATION + 3.0, 0.01)
            ego_s = sc.path.s_of_t(grid)

            def lead(t_b: float) -> Callable[[Any], Any]:
                v_b = float(np.interp(t_b + 0.05, grid, ego_s)
                            - np.interp(t_b - 0.05, grid, ego_s)) / 0.1
                s_b = float(np.interp(t_b, grid, ego_s)) + gap

                def s(t: Any) -> Any:
                    t = np.asarray(t, float)
                    tau = np.clip(t - t_b, 0.0, v_b / a)
                    return np.where(t < t_b, sc.path.s_of_t(t) + gap,
                                    s_b + v_b * tau - 0.5 * a * tau ** 2)
                return s

            def contact(t_b: float) -> float:
                hit = np.nonzero(ego_s + S.VEH_FRONT >= lead(t_b)(grid) - car_l / 2)[0]
                return float(grid[hit[0]]) if len(hit) else np.inf

            t_b = min(np.arange(0.5, sc.t_conflict, 0.02),
                      key=lambda tb: abs(contact(tb) - sc.t_conflict))
            return S.Mover(1, "car", S.PathMotion(sc.path, lead(float(t_b))), rng)
        return make

    S.HOLDOUT_MOVERS.update({"stopped_car": stopped(0.0),
                             "stopped_car_next_lane": stopped(3.2),
                             "braking_car": braking(4.0, 15.0)})
    S.SCENARIOS.update({
        "car_stopped_k00": dict(seg="k00_straight", mover="stopped_car", collide=True,
                                text="car standing in the ego lane, ego about 33 km/h"),
        "car_stopped_k06": dict(seg="k06_straight", mover="stopped_car", collide=True,
                                text="car standing in the ego lane, ego about 42 km/h"),
        "lead_braking_k06": dict(seg="k06_straight", mover="braking_car", collide=True,
                                 text="lead car 15 m ahead brakes at 4 m/s^2 to a stop"),
        "car_stopped_next_lane_k06": dict(seg="k06_straight", mover="stopped_car_next_lane",
                                          collide=False, text="car standing in the next lane"),
    })


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    missing = [f for f in ("generate.py", "scenarios.py") if not (Path(argv[0]) / f).is_file()]
    if missing:
        print(f"{argv[0]}: not the kitti-street world (no {', '.join(missing)})", file=sys.stderr)
        return 2
    sys.path.insert(0, argv[0])
    import scenarios  # the world's, from its directory

    register(scenarios)
    import generate

    return int(generate.main(argv[1:]))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
