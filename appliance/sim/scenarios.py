"""The test drives. Each scenario is a function of the ego outline that returns a :class:`Plan`.

Scenario time ``tau`` (s): the ego's rear axle is at the world origin at
``tau = 0``, heading along +x; on a straight road arc length ``s`` = world x.
The recording covers the ``duration_s`` seconds that end at the collision
(collision scenarios) or at ``end_s``; ``--duration`` changes how much lead-in
there is, not the end, so the event stays in the recording.

Collision courses are exact constant-velocity courses (constant bearing): the
mover barely moves in the image and only grows. Near misses are the same
courses shifted in time so that the footprints pass 1 m apart.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from appliance.sim.collision import Vehicle, closest_approach
from appliance.sim.ego import EgoPath, EgoPlan, PtuMove, PtuPlan
from appliance.sim.movers import (
    SIZES,
    MoverPlan,
    Trajectory,
    crossing_course,
    stand_then_cross,
    stop_at,
)
from appliance.sim.street import ClearView, Intersection, Overhead, ParkedCar, StreetPlan

KMH = 1.0 / 3.6  # m/s per km/h
WALK = 5.0 * KMH  # Euro NCAP adult walking speed


@dataclass(frozen=True)
class Plan:
    """Everything a scenario fixes. ``end_s`` None: the drive ends at the collision."""

    ego: EgoPlan
    duration_s: float
    end_s: float | None = None
    street: StreetPlan = field(default_factory=StreetPlan)
    movers: tuple[MoverPlan, ...] = ()
    ptu: PtuPlan = field(default_factory=PtuPlan)


@dataclass(frozen=True)
class Scenario:
    """``description``: one line (``simulate --list``); ``details``: the function's docstring."""

    name: str
    description: str
    collision: bool  # what the scenario is built to produce (the tests check it)
    make: Callable[[Vehicle], Plan]
    details: str = ""


def _shifted(traj: Trajectory, dt: float) -> Trajectory:
    return Trajectory(tuple((t + dt, x, y) for t, x, y in traj.waypoints))


def near_miss(
    course: Trajectory,
    kind: str,
    ego: EgoPlan,
    vehicle: Vehicle,
    gap_m: float,
    in_front: bool,
    window: tuple[float, float],
) -> Trajectory:
    """Shift a collision course in time (earlier: passes in front; later: behind) until the
    footprints' closest approach is ``gap_m``."""
    path = EgoPath(ego, window[0] - 10.0, window[1] + 10.0)
    sign = -1.0 if in_front else 1.0

    def gap(dt: float) -> float:
        return closest_approach(path, _shifted(course, sign * dt), SIZES[kind], vehicle, *window)[0]

    lo, hi = 0.0, 6.0
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) < gap_m else (lo, mid)
    return _shifted(course, sign * hi)


# ---------------------------------------------------------------- the paper's three collisions


def pedestrian_crossing_nearside(v: Vehicle) -> Plan:
    """Nearside crossing as Euro NCAP CPNA-25 (ego 35 km/h, adult walking 5 km/h in from the
    right, impact at 25 % of the width), but out from between two parked cars as in the paper's
    sequence: the nearer car hides the body below its roof line while the pedestrian crosses the
    parking lane (about 3.0 s to 1.2 s before impact)."""
    return _between_parked_cars(v, stop_y=None)


def pedestrian_stops_behind_parked_car(v: Vehicle) -> Plan:
    """As pedestrian_crossing_nearside, but the pedestrian stops between the parked cars, hidden
    below the nearer car's roof line, and waits while the car passes: what a track coasted
    through the occlusion cannot know (it predicts the walk to go on)."""
    return _between_parked_cars(v, stop_y=-3.6)


def _between_parked_cars(v: Vehicle, stop_y: float | None) -> Plan:
    ego_speed, T = 35 * KMH, 8.0
    walk = crossing_course(
        ego_speed=ego_speed,
        aim_x=v.front,
        mover_speed=WALK,
        from_right=True,
        aim_y=-v.width / 2 + 0.25 * v.width,
        aim_tau=T,
        start_y=-6.4,
        end_y=6.0,
    )
    x_line = walk.waypoints[0][1]
    occluder, behind = x_line - 1.5 - 2.25, x_line + 0.8 + 2.25
    street = StreetPlan(
        parked=(ParkedCar(occluder, "right", 4.5, 1), ParkedCar(behind, "right", 4.5, 5)),
        clear_view=(ClearView(x_line - 45.0, occluder, "right"),),
    )
    if stop_y is None:    # on to the collision, where the drive ends
        course, end_s = walk, None
        what = "adult, steps out between parked cars"
    else:
        course, end_s = stop_at(walk, stop_y=stop_y), T + 1.0
        what = "adult, stops hidden between parked cars"
    ped = MoverPlan("pedestrian", stand_then_cross(course, -60.0), what)
    return Plan(EgoPlan(speed=((0.0, ego_speed),)), duration_s=8.0, end_s=end_s, street=street,
                movers=(ped,))


def car_crossing_intersection(v: Vehicle) -> Plan:
    """Ego 40 km/h towards an intersection; a car (20 km/h) pulls in from the right on the cross
    street on a collision course aimed at the camera: seen from the camera its bearing (27 deg
    right) is exactly constant. The PTU pans 20 deg right towards it 8 s before impact; the
    near-right corner is an open car park so the car is in view early."""
    ego_speed, car_speed, T = 40 * KMH, 20 * KMH, 10.0
    course = crossing_course(
        ego_speed=ego_speed,
        aim_x=v.camera_x,
        mover_speed=car_speed,
        from_right=True,
        aim_y=v.camera_y,
        aim_tau=T,
        start_y=-200.0,
        end_y=60.0,
    )
    s_cross = course.waypoints[0][1] - 1.75  # the car keeps to its right-hand lane
    street = StreetPlan(
        intersections=(Intersection(s_cross, ("near_right",), 70.0),),
        clear_view=(ClearView(s_cross - 150.0, s_cross, "right"),),
    )
    ptu = PtuPlan(moves=(PtuMove(start=T - 8.0, duration=1.0, pan=-0.35),))
    car = MoverPlan("car", course, "car from the right on the cross street")
    return Plan(
        EgoPlan(speed=((0.0, ego_speed),)), duration_s=10.0, street=street, movers=(car,), ptu=ptu
    )


def cyclist_crossing_intersection(v: Vehicle) -> Plan:
    """Ego 30 km/h towards an intersection; a cyclist (15 km/h) comes from the left on the cross
    street on a collision course aimed at the camera (constant bearing, 27 deg left). The PTU
    pans 20 deg left towards it 8 s before impact."""
    ego_speed, bike_speed, T = 30 * KMH, 15 * KMH, 10.0
    course = crossing_course(
        ego_speed=ego_speed,
        aim_x=v.camera_x,
        mover_speed=bike_speed,
        from_right=False,
        aim_y=v.camera_y,
        aim_tau=T,
        start_y=120.0,
        end_y=-40.0,
    )
    s_cross = course.waypoints[0][1] + 2.5  # rides 1 m from the right kerb of its lane
    street = StreetPlan(
        intersections=(Intersection(s_cross, ("near_left",), 60.0),),
        clear_view=(ClearView(s_cross - 120.0, s_cross, "left"),),
    )
    ptu = PtuPlan(moves=(PtuMove(start=T - 8.0, duration=1.0, pan=0.35),))
    bike = MoverPlan("cyclist", course, "cyclist from the left on the cross street")
    return Plan(
        EgoPlan(speed=((0.0, ego_speed),)), duration_s=10.0, street=street, movers=(bike,), ptu=ptu
    )


# ---------------------------------------------------------------- no collision


def pedestrian_stops_at_kerb(v: Vehicle) -> Plan:
    """Ego 30 km/h; a pedestrian walks towards the road on a collision course but stops at the
    kerb and waits while the car passes."""
    ego_speed, T = 30 * KMH, 7.0
    walk = crossing_course(
        ego_speed=ego_speed,
        aim_x=v.front,
        mover_speed=WALK,
        from_right=True,
        aim_y=-v.width / 4,
        aim_tau=T,
        start_y=-6.4,
        end_y=6.0,
    )
    x_line = walk.waypoints[0][1]
    ped = MoverPlan(
        "pedestrian",
        stand_then_cross(stop_at(walk, stop_y=-4.15), -60.0),
        "pedestrian who stops at the kerb",
    )
    street = StreetPlan(clear_view=(ClearView(x_line - 35.0, x_line + 4.0, "right"),))
    return Plan(
        EgoPlan(speed=((0.0, ego_speed),)),
        duration_s=8.0,
        end_s=T + 1.0,
        street=street,
        movers=(ped,),
    )


def car_crosses_ahead(v: Vehicle) -> Plan:
    """Ego 40 km/h; a car (30 km/h) from the left crosses the intersection when the ego is still
    30 m away: it moves quickly across the image and never comes near."""
    ego_speed, car_speed, t_cross = 40 * KMH, 30 * KMH, 6.0
    x_line = v.front + ego_speed * t_cross + 30.0
    car = Trajectory(
        ((t_cross - 80.0 / car_speed, x_line, 80.0), (t_cross + 80.0 / car_speed, x_line, -80.0))
    )
    s_cross = x_line + 1.75
    street = StreetPlan(
        intersections=(Intersection(s_cross, ("near_left",), 60.0),),
        clear_view=(ClearView(s_cross - 80.0, s_cross, "left"),),
    )
    return Plan(
        EgoPlan(speed=((0.0, ego_speed),)),
        duration_s=10.0,
        end_s=10.0,
        street=street,
        movers=(MoverPlan("car", car, "car crossing well ahead"),),
    )


def bend_static(v: Vehicle) -> Plan:
    """Ego 35 km/h through a left bend (yaw rate up to 0.13 rad/s, radius 75 m) with only the
    static scene: every flow is the ego's own."""
    ego = EgoPlan(
        speed=((0.0, 35 * KMH),),
        yaw_rate=((0.0, 0.0), (2.0, 0.0), (3.5, 0.13), (7.5, 0.13), (9.0, 0.0)),
    )
    return Plan(ego, duration_s=11.0, end_s=11.0, street=StreetPlan(parking_occupancy=0.7))


def lead_car_driving_away(v: Vehicle) -> Plan:
    """Ego 45 km/h behind a lead car 12 m ahead in the same lane, which accelerates at 1.5 m/s^2
    from 45 to 65 km/h and pulls away."""
    v0, v1, a, t_acc = 45 * KMH, 65 * KMH, 1.5, 2.0
    x0 = v.front + 12.0 + SIZES["car"][0] / 2
    taus = np.concatenate(
        [
            [-30.0, t_acc],
            np.arange(t_acc + 0.25, t_acc + (v1 - v0) / a, 0.25),
            [t_acc + (v1 - v0) / a],
        ]
    )
    dt = np.clip(taus - t_acc, 0.0, (v1 - v0) / a)
    x = x0 + v0 * taus + 0.5 * a * dt**2
    lead = Trajectory(tuple((float(t), float(xx), 0.0) for t, xx in zip(taus, x)))
    return Plan(
        EgoPlan(speed=((0.0, v0),)),
        duration_s=10.0,
        end_s=10.0,
        movers=(MoverPlan("car", lead, "lead car pulling away"),),
    )


def lead_car_braking(v: Vehicle) -> Plan:
    """Rear-end course as Euro NCAP CCRb (ego and lead car at 50 km/h, 12 m apart in the same
    lane; the lead brakes at 2 m/s^2 towards a standstill); the ego does not brake and hits it
    about 3.5 s after the brake onset. The closing speed grows all the way: a time to collision
    from the constant closing speed of the moment is always too long."""
    v0, decel, gap, t_brake = 50 * KMH, 2.0, 12.0, -3.0
    x0 = v.front + gap + SIZES["car"][0] / 2  # lead's centre at tau = t_brake, relative to ego
    t_stop = v0 / decel
    taus = np.concatenate([[-30.0], np.arange(0.0, t_stop, 0.1), [t_stop, t_stop + 60.0]])
    t = np.minimum(taus, t_stop)
    x = x0 + v0 * (t_brake + t) - 0.5 * decel * np.maximum(t, 0.0) ** 2
    taus = taus + t_brake
    lead = Trajectory(tuple((float(tt), float(xx), 0.0) for tt, xx in zip(taus, x)))
    return Plan(
        EgoPlan(speed=((0.0, v0),)),
        duration_s=8.0,
        movers=(MoverPlan("car", lead, "lead car braking at 2 m/s^2"),),
    )


def _passing(v: Vehicle, in_front: bool) -> Plan:
    ego_speed, T = 30 * KMH, 7.0
    ego = EgoPlan(speed=((0.0, ego_speed),))
    walk = crossing_course(
        ego_speed=ego_speed,
        aim_x=v.front,
        mover_speed=WALK,
        from_right=True,
        aim_y=0.0,
        aim_tau=T,
        start_y=-6.4,
        end_y=8.0,
    )
    walk = near_miss(walk, "pedestrian", ego, v, 1.0, in_front, (T - 5.0, T + 5.0))
    x_line = walk.waypoints[0][1]
    path = EgoPath(ego, T - 10.0, T + 10.0)
    _, t_close = closest_approach(path, walk, SIZES["pedestrian"], v, T - 5.0, T + 5.0)
    ped = MoverPlan(
        "pedestrian",
        stand_then_cross(walk, -60.0),
        "pedestrian passing 1 m " + ("in front of the bumper" if in_front else "behind the car"),
    )
    street = StreetPlan(clear_view=(ClearView(x_line - 35.0, x_line + 4.0, "right"),))
    return Plan(ego, duration_s=8.0, end_s=round(t_close + 0.5, 3), street=street, movers=(ped,))


def pedestrian_passes_front(v: Vehicle) -> Plan:
    """Near miss: ego 30 km/h; a pedestrian (5 km/h, from the right) crosses so that the closest
    approach is 1 m in front of the bumper."""
    return _passing(v, True)


def pedestrian_passes_behind(v: Vehicle) -> Plan:
    """Near miss: ego 30 km/h; a pedestrian (5 km/h, from the right) reaches the lane just after
    the car and passes 1 m behind it."""
    return _passing(v, False)


def _standing(v: Vehicle, kind: str, speed_kmh: float, lateral_m: float, label: str,
              end_s: float | None = None) -> Plan:
    """Something of class ``kind`` standing still ``lateral_m`` left of the lane's centre, where
    the ego's bumper, driving at ``speed_kmh`` without braking, reaches it (or passes it) 7 s
    on; ``end_s`` None: the drive ends at the collision."""
    v0, T = speed_kmh * KMH, 7.0
    x = v.front + v0 * T + SIZES[kind][0] / 2   # the bumper reaches its near side at T
    still = Trajectory(((-30.0, x, lateral_m), (T + 60.0, x, lateral_m)))
    return Plan(EgoPlan(speed=((0.0, v0),)), duration_s=8.0, end_s=end_s,
                movers=(MoverPlan(kind, still, label),))


def _stopped_car(v: Vehicle, speed_kmh: float, lateral_m: float) -> Plan:
    if lateral_m == 0.0:      # in the lane the drive ends at the collision
        return _standing(v, "car", speed_kmh, 0.0, "car standing in the lane")
    return _standing(v, "car", speed_kmh, lateral_m, "car standing in the next lane", 7.5)


def car_stopped_in_lane_30(v: Vehicle) -> Plan:
    """Euro NCAP CCRs / NHTSA FCW test 1 at 30 km/h: a car stands in the ego lane; the ego
    drives at it at constant speed and does not brake. Nothing in the scene moves: to a motion
    detector the car is static scene; only its parallax (it stands up from the road) sets it
    apart."""
    return _stopped_car(v, 30.0, 0.0)


def car_stopped_in_lane_60(v: Vehicle) -> Plan:
    """The same at 60 km/h (the car is 133 m ahead at the start, 40 m at 2.4 s before contact)."""
    return _stopped_car(v, 60.0, 0.0)


def car_stopped_next_lane(v: Vehicle) -> Plan:
    """No collision: a car stands in the next lane to the left (3.5 m), the ego passes it at
    50 km/h."""
    return _stopped_car(v, 50.0, 3.5)


def pedestrian_standing_in_lane(v: Vehicle) -> Plan:
    """Euro NCAP AEB pedestrian, stationary: an adult stands still in the middle of the ego
    lane, facing the car; the ego drives at them at 35 km/h and does not brake. Nothing in the
    scene moves: only the pedestrian's parallax (standing up from the road) sets them apart."""
    return _standing(v, "pedestrian", 35.0, 0.0, "pedestrian standing in the lane")


def lead_car_stops_in_lane(v: Vehicle) -> Plan:
    """Ego and lead car at 40 km/h, 25 m apart in the same lane; the lead brakes at 5 m/s^2
    (0.5 g) to a standstill and stands; the ego does not brake and hits it about 1.1 s after it
    stopped. One object, moving and then standing: one track and one threat throughout."""
    v0, decel, gap, t_brake = 40 * KMH, 5.0, 25.0, 3.0
    x0 = v.front + gap + SIZES["car"][0] / 2   # the lead's centre at tau = 0
    t_stop = v0 / decel
    taus = np.concatenate([[-30.0, 0.0], t_brake + np.arange(0.0, t_stop, 0.1),
                           [t_brake + t_stop, t_brake + t_stop + 60.0]])
    t = np.clip(taus - t_brake, 0.0, t_stop)
    x = x0 + v0 * np.minimum(taus, t_brake) + v0 * t - 0.5 * decel * t**2
    lead = Trajectory(tuple((float(tt), float(xx), 0.0) for tt, xx in zip(taus, x)))
    return Plan(EgoPlan(speed=((0.0, v0),)), duration_s=8.0,
                movers=(MoverPlan("car", lead, "lead car braking to a stop at 5 m/s^2"),))


def pedestrian_stops_in_lane(v: Vehicle) -> Plan:
    """Ego 30 km/h; a pedestrian crosses from the right and stops in the middle of the ego lane
    about 2.8 s before the car reaches them, and stands; the ego does not brake. One object,
    moving and then standing: one track and one threat throughout."""
    ego_speed, T, standing = 30 * KMH, 7.0, 3.0
    walk = crossing_course(
        ego_speed=ego_speed,
        # the lane's centre ``standing`` s before the bumper reaches them at T
        aim_x=v.front + ego_speed * standing + SIZES["pedestrian"][0] / 2,
        mover_speed=WALK,
        from_right=True,
        aim_y=0.0,
        aim_tau=T - standing,
        start_y=-6.4,
        end_y=6.0,
    )
    ped = MoverPlan("pedestrian", stand_then_cross(stop_at(walk, stop_y=0.0), -60.0),
                    "pedestrian who stops in the lane")
    return Plan(EgoPlan(speed=((0.0, ego_speed),)), duration_s=8.0, movers=(ped,))


def lead_car_stops_ego_brakes(v: Vehicle) -> Plan:
    """No collision: ego and lead car at 40 km/h, 15 m apart in the same lane; the lead brakes
    at 3 m/s^2 (0.3 g) to a standstill and the ego, 0.5 s later, brakes harder (4 m/s^2) and
    stops about 14 m behind it (the CAN speed falls to 0). The driver is already doing what a
    warning would ask for."""
    v0, decel, gap, t_brake, reaction, ego_decel = 40 * KMH, 3.0, 15.0, 2.0, 0.5, 4.0
    x0 = v.front + gap + SIZES["car"][0] / 2   # the lead's centre at tau = 0
    t_stop = v0 / decel
    taus = np.concatenate([[-30.0, 0.0], t_brake + np.arange(0.0, t_stop, 0.1),
                           [t_brake + t_stop, t_brake + t_stop + 60.0]])
    t = np.clip(taus - t_brake, 0.0, t_stop)
    x = x0 + v0 * np.minimum(taus, t_brake) + v0 * t - 0.5 * decel * t**2
    lead = Trajectory(tuple((float(tt), float(xx), 0.0) for tt, xx in zip(taus, x)))
    ego_brake = t_brake + reaction
    ego = EgoPlan(speed=((0.0, v0), (ego_brake, v0), (ego_brake + v0 / ego_decel, 0.0)))
    return Plan(ego, duration_s=8.0, end_s=7.0,
                movers=(MoverPlan("car", lead, "lead car braking to a stop at 3 m/s^2"),))


def box_in_lane(v: Vehicle) -> Plan:
    """A crate 0.5 m on a side stands in the ego lane, its centre 0.2 m left of the lane's; the
    ego drives at it at 35 km/h and does not brake. Nothing moves: it stands up from the road
    by 0.5 m, little more than the obstacle cue's lowest probe (0.4 m)."""
    return _standing(v, "box", 35.0, 0.2, "crate standing in the lane")


def flat_things_in_lane(v: Vehicle) -> Plan:
    """No collision: a manhole cover (0.4 m left of the lane's centre), a painted arrow and a
    speed bump 7 cm high across the lane lie on the road 3.5, 5 and 6.5 s ahead at 40 km/h; the
    ego drives over each (all lower than ``collision.GROUND_CLEARANCE_M``). Flat things on the
    road are no obstacles: nothing stands up from it."""
    v0 = 40 * KMH
    things = (("manhole", 3.5, 0.4, "manhole cover"), ("arrow", 5.0, 0.0, "painted arrow"),
              ("speed_bump", 6.5, 0.0, "speed bump"))
    movers = []
    for kind, tau, y, label in things:
        x = v.front + v0 * tau + SIZES[kind][0] / 2   # the bumper reaches it at tau
        movers.append(MoverPlan(kind, Trajectory(((-30.0, x, y), (60.0, x, y))), label))
    return Plan(EgoPlan(speed=((0.0, v0),)), duration_s=8.0, end_s=7.5, movers=tuple(movers))


def overhead_sign_and_bridge(v: Vehicle) -> Plan:
    """No collision: the ego drives at 50 km/h under a sign gantry (its signs' lower edge 5.2 m
    over the road) 3 s ahead and then under a concrete bridge (clearance 4.5 m, 9 m deep) 6 s
    ahead. Both stand across the whole corridor, nearer than the road beyond them, but far above
    any car: no obstacles."""
    v0 = 50 * KMH
    street = StreetPlan(overhead=(Overhead(v.front + v0 * 3.0, "sign", 5.2),
                                  Overhead(v.front + v0 * 6.0 + 4.5, "bridge", 4.5)))
    return Plan(EgoPlan(speed=((0.0, v0),)), duration_s=8.0, end_s=7.5, street=street)


def _scenario(fn: Callable[[Vehicle], Plan], collision: bool, description: str) -> Scenario:
    return Scenario(fn.__name__, description, collision, fn, " ".join((fn.__doc__ or "").split()))


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        _scenario(
            pedestrian_crossing_nearside,
            True,
            "collision: pedestrian steps out between parked cars, 35 km/h, impact at 25 % width",
        ),
        _scenario(
            car_crossing_intersection,
            True,
            "collision: car from the right at an intersection, 40 km/h vs 20 km/h, PTU pans right",
        ),
        _scenario(
            cyclist_crossing_intersection,
            True,
            "collision: cyclist from the left at an intersection, 30 vs 15 km/h, PTU pans left",
        ),
        _scenario(
            lead_car_braking,
            True,
            "collision: lead car 12 m ahead brakes at 2 m/s^2 from 50 km/h (CCRb), ego does not",
        ),
        _scenario(
            car_stopped_in_lane_30,
            True,
            "collision: car standing in the lane, ego 30 km/h does not brake (CCRs)",
        ),
        _scenario(
            car_stopped_in_lane_60,
            True,
            "collision: car standing in the lane, ego 60 km/h does not brake (CCRs)",
        ),
        _scenario(
            pedestrian_standing_in_lane,
            True,
            "collision: pedestrian standing still in the lane, ego 35 km/h does not brake",
        ),
        _scenario(
            lead_car_stops_in_lane,
            True,
            "collision: lead car 25 m ahead brakes at 5 m/s^2 to a stop, 40 km/h, ego does not",
        ),
        _scenario(
            pedestrian_stops_in_lane,
            True,
            "collision: pedestrian crosses and stops in the lane, 30 km/h, ego does not brake",
        ),
        _scenario(
            box_in_lane,
            True,
            "collision: crate (0.5 m) standing in the lane, ego 35 km/h does not brake",
        ),
        _scenario(
            pedestrian_stops_at_kerb,
            False,
            "no collision: pedestrian on a collision course stops at the kerb, 30 km/h",
        ),
        _scenario(
            pedestrian_stops_behind_parked_car,
            False,
            "no collision: pedestrian stops hidden between parked cars, 35 km/h",
        ),
        _scenario(
            car_crosses_ahead,
            False,
            "no collision: car crosses the intersection 30 m ahead, 40 km/h",
        ),
        _scenario(
            bend_static, False, "no collision: left bend (R 75 m) at 35 km/h, static scene only"
        ),
        _scenario(
            lead_car_driving_away,
            False,
            "no collision: lead car 12 m ahead accelerates away, 45 km/h",
        ),
        _scenario(
            car_stopped_next_lane,
            False,
            "no collision: car standing in the next lane, passed at 50 km/h",
        ),
        _scenario(
            lead_car_stops_ego_brakes,
            False,
            "no collision: lead car 15 m ahead brakes to a stop, the ego brakes harder, 40 km/h",
        ),
        _scenario(
            flat_things_in_lane,
            False,
            "no collision: manhole cover, painted arrow and speed bump in the lane, 40 km/h",
        ),
        _scenario(
            overhead_sign_and_bridge,
            False,
            "no collision: under a sign gantry (5.2 m) and a bridge (4.5 m), 50 km/h",
        ),
        _scenario(
            pedestrian_passes_front,
            False,
            "near miss: pedestrian passes 1 m in front of the bumper, 30 km/h",
        ),
        _scenario(
            pedestrian_passes_behind,
            False,
            "near miss: pedestrian passes 1 m behind the car, 30 km/h",
        ),
    )
}
