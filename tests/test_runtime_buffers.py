"""Ring buffers and sensor synchronisation (no threads sleeping: events and timeouts only)."""

from __future__ import annotations

import threading

import pytest

from appliance.runtime.sensor_sync import SensorSync, SignalHistory
from drivers.handoff import Handoff


def test_overwrite_oldest_counts_drops() -> None:
    rb: Handoff[int] = Handoff(3)
    for i in range(5):
        rb.put(i)
    assert rb.drain() == [2, 3, 4]
    s = rb.stats()
    assert (s.pushed, s.taken, s.dropped, s.size) == (5, 3, 2, 0)


def test_take_newest_skips_and_counts_the_older_frames() -> None:
    rb: Handoff[int] = Handoff(4)
    for i in range(3):
        rb.put(i)
    assert rb.take_newest(timeout=0) == 2
    assert rb.stats().dropped == 2
    assert rb.take_newest(timeout=0.01) is None


def test_consumer_wakes_when_a_producer_pushes() -> None:
    rb: Handoff[str] = Handoff(2)
    got: list[str | None] = []
    waiting = threading.Event()

    def consume() -> None:
        waiting.set()
        got.append(rb.get(timeout=5.0))

    th = threading.Thread(target=consume)
    th.start()
    assert waiting.wait(5.0)
    rb.put("frame")
    th.join(5.0)
    assert got == ["frame"]


def test_close_releases_a_waiting_consumer() -> None:
    rb: Handoff[int] = Handoff(2)
    result: list[int | None] = [0]
    th = threading.Thread(target=lambda: result.__setitem__(0, rb.take_newest(timeout=10.0)))
    th.start()
    rb.close()
    th.join(5.0)
    assert not th.is_alive() and result[0] is None


def test_capacity_must_be_positive() -> None:
    with pytest.raises(ValueError):
        Handoff(0)


def test_interpolation_hold_and_staleness() -> None:
    h = SignalHistory()
    h.add(1.0, 10.0)
    h.add(1.02, 12.0)
    r = h.at(1.01, stale_s=0.2)
    assert r is not None and r.value == pytest.approx(11.0) and r.fresh
    held = h.at(1.1, stale_s=0.2)
    assert held is not None and held.value == 12.0 and held.fresh
    stale = h.at(1.5, stale_s=0.2)
    assert stale is not None and stale.value == 12.0 and not stale.fresh
    assert SignalHistory().at(1.0, 0.2) is None


def test_the_ptu_is_extrapolated_past_its_newest_answer_can_is_held() -> None:
    """A pan at 0.35 rad/s answered at 20 Hz: 30 ms after the last answer the pan is where
    the last two answers' slope puts it (holding it would be 10 mrad = 0.6 deg behind);
    never further than stale_s ahead. CAN is held."""
    s = SensorSync(can_stale_s=0.2, ptu_stale_s=0.1)
    for k in range(3):
        s.add_ptu(0.05 * k, 0.35 * 0.05 * k, 0.0)
        s.add_speed(0.05 * k, 10.0 + k)
        s.add_yaw_rate(0.05 * k, 0.0)
    x = s.sample(0.13)
    assert x.pan_rad == pytest.approx(0.35 * 0.13) and x.ptu_valid
    assert x.speed_m_s == 12.0
    late = s.sample(0.5)
    assert late.pan_rad == pytest.approx(0.35 * (0.1 + 0.1)) and not late.ptu_valid


def test_out_of_order_samples_stay_sorted() -> None:
    h = SignalHistory()
    for t, v in [(1.0, 1.0), (1.2, 3.0), (1.1, 2.0)]:
        h.add(t, v)
    r = h.at(1.15, 1.0)
    assert r is not None and r.value == pytest.approx(2.5)


def test_history_is_trimmed() -> None:
    h = SignalHistory(keep_s=1.0)
    for i in range(1000):
        h.add(i * 0.01, float(i))
    assert len(h) <= 102


def test_sensor_sample_flags() -> None:
    s = SensorSync(can_stale_s=0.2, ptu_stale_s=0.2)
    assert not s.sample(0.0).can_valid  # nothing yet
    s.add_speed(0.0, 10.0)
    s.add_yaw_rate(0.0, 0.1)
    s.add_ptu(0.0, 0.2, -0.1)
    x = s.sample(0.05)
    assert (
        x.can_valid
        and x.ptu_valid
        and (x.speed_m_s, x.yaw_rate_rad_s, x.pan_rad) == (10.0, 0.1, 0.2)
    )
    late = s.sample(1.0)
    assert not late.can_valid and not late.ptu_valid and late.speed_m_s == 10.0  # held, flagged


def test_no_ptu_means_fixed_at_zero_and_valid() -> None:
    s = SensorSync(0.2, 0.2, ptu_present=False)
    x = s.sample(3.0)
    assert x.ptu_valid and x.pan_rad == 0.0 and x.tilt_rad == 0.0
