"""Allocator: limits respected, commands consistent, tether kept taut, deterministic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from splitter_ik.core.allocator import Allocation, AllocatorConfig, TetherLimbAllocator
from splitter_ik.core.tether import hemi_mass_kg
from splitter_model.actuators import TETHER_INDEX, actuator_limits
from splitter_model.kinematics import joint_positions_from_radii, radii_from_joint_positions
from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia

MODEL = RobotModel()
DT = 0.01
PERIOD_NS = 10_000_000
LIMB = slice(0, 24)
TETHER = TETHER_INDEX


def _random_walk_setpoints(seed: int, n: int) -> np.ndarray:
    """Setpoints that jump around the reachable set and beyond it."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n // 40):
        radii = rng.uniform(MODEL.radii_min_m * 0.8, MODEL.radii_max_m * 1.2)
        out += [principal_inertia(MODEL, radii)] * 40
    return np.array(out)


def _run(
    allocator: TetherLimbAllocator, setpoints: np.ndarray, w: list[float] | None
) -> list[Allocation]:
    return [allocator.allocate(k * PERIOD_NS, sp, w) for k, sp in enumerate(setpoints)]


@pytest.mark.parametrize("w", [None, [0.0, 1.0, 0.0], [-0.3, -0.9, 0.9], [0.0, 0.2, 0.1]])
def test_speed_and_acceleration_limits_hold(w: list[float] | None) -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    allocations = _run(allocator, _random_walk_setpoints(1, 1200), w)
    q = np.array([a.joint_position for a in allocations])
    v = np.array([a.joint_velocity for a in allocations])
    # a piecewise-linear trajectory from the initial radii: q_{k+1} = q_k + v_k dt
    np.testing.assert_allclose(q[0], joint_positions_from_radii(MODEL, PAPER_INITIAL_RADII_M))
    np.testing.assert_allclose(q[:-1] + v[:-1] * DT, q[1:], rtol=0.0, atol=1e-12)
    dv = np.diff(np.vstack([np.zeros(25), v]), axis=0) / DT
    # the simulator rejects a command over a limit: speeds and positions hold exactly
    limits = actuator_limits(MODEL)
    assert np.all(np.abs(v) <= limits.speed_max)
    assert np.all((q >= limits.position_min) & (q <= limits.position_max))
    eps = 1e-9  # rounding of positions of a few metres, differenced twice over 10 ms
    assert np.max(np.abs(v[:, LIMB])) <= MODEL.joint_speed_max_rad_s * (1 + eps)
    config = allocator.config  # commanded accelerations keep the servo headroom
    limb_accel = MODEL.joint_acceleration_max_rad_s2 * config.limb_acceleration_fraction
    tether_accel = MODEL.tether_acceleration_max_m_s2 * config.tether_acceleration_fraction
    assert np.max(np.abs(dv[:, LIMB])) <= limb_accel * (1 + eps)
    assert np.max(np.abs(v[:, TETHER])) <= MODEL.tether_speed_max_m_s * (1 + eps)
    assert np.max(np.abs(dv[:, TETHER])) <= tether_accel * (1 + eps)
    assert np.max(np.abs(dv[:, LIMB])) == pytest.approx(limb_accel, rel=1e-9)  # and use it
    assert np.all(q[:, TETHER] >= MODEL.tether_length_min_m - eps)
    assert np.all(q[:, TETHER] <= MODEL.tether_length_max_m + eps)
    # the limits actually bind somewhere in this sequence
    assert any(a.rate_limited for a in allocations)
    if w is None or w[1] ** 2 + w[2] ** 2 >= 1.0:  # enough spin to let the reel run freely
        assert np.max(np.abs(v[:, TETHER])) == pytest.approx(MODEL.tether_speed_max_m_s, rel=1e-9)


def test_commands_are_the_ik_of_the_reported_radii() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    for a in _run(allocator, _random_walk_setpoints(2, 400), [0.0, 1.0, 0.0]):
        np.testing.assert_allclose(a.joint_position, joint_positions_from_radii(MODEL, a.radii_m))
        np.testing.assert_allclose(radii_from_joint_positions(MODEL, a.joint_position), a.radii_m)
        np.testing.assert_allclose(a.achieved_inertia_kg_m2, principal_inertia(MODEL, a.radii_m))
        assert np.all(np.isfinite(a.joint_position)) and np.all(np.isfinite(a.joint_velocity))


def test_reachable_setpoint_is_reached_and_held_exactly() -> None:
    target_radii = np.array([2.1, 0.33, 0.15])
    target = principal_inertia(MODEL, target_radii)
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    allocations = _run(allocator, np.array([target] * 300), [0.0, 1.0, 0.0])
    assert allocations[0].rate_limited and not allocations[0].saturated
    last = allocations[-1]
    assert not last.rate_limited
    np.testing.assert_allclose(last.radii_m, target_radii, atol=1e-12)
    np.testing.assert_allclose(last.achieved_inertia_kg_m2, target, rtol=1e-12)
    np.testing.assert_allclose(last.joint_velocity, 0.0, atol=1e-9)
    # the tether travels 1.4 m: at least the time the reel needs at its top speed
    moving = [a for a in allocations if abs(a.joint_velocity[TETHER]) > 1e-12]
    assert len(moving) * DT >= 1.4 / MODEL.tether_speed_max_m_s


def test_unreachable_setpoint_is_projected_and_flagged() -> None:
    allocator = TetherLimbAllocator(MODEL)
    a = allocator.allocate(0, [0.1, 300.0, 100.0], None)
    assert a.saturated and not a.rate_limited  # first tick without history: at the target
    assert np.all(a.radii_m <= MODEL.radii_max_m + 1e-12)
    np.testing.assert_allclose(a.requested_inertia_kg_m2, [0.1, 300.0, 100.0])
    assert np.all(np.isfinite(a.achieved_inertia_kg_m2))


def _spin_about_y(radii: np.ndarray, momentum_y: float) -> list[float]:
    """Torque-free spin about the principal y axis: w_y = H_y / Iyy (H_y conserved)."""
    return [0.0, momentum_y / float(principal_inertia(MODEL, radii)[1]), 0.0]


@pytest.mark.parametrize("momentum_y", [10.0, 40.0, 150.0])
def test_tether_reels_only_as_fast_as_keeps_it_taut(momentum_y: float) -> None:
    """Reel out toward 6 m then in to 1.4 m under a torque-free spin (w from conserved H).

    Paying out slows the spin (H = Iyy w_y), so at low momentum the tether can only
    go as far as the spin still holds it taut with the margin; there it is held.
    """
    margin = 2.0
    m_h = hemi_mass_kg(MODEL)
    allocator = TetherLimbAllocator(
        MODEL, AllocatorConfig(tension_margin_n=margin), initial_radii_m=[1.0, 0.2, 0.2]
    )
    setpoints = [principal_inertia(MODEL, [3.0, 0.2, 0.2])] * 1500 + [
        principal_inertia(MODEL, [0.7, 0.2, 0.2])
    ] * 1500
    radii = np.array([1.0, 0.2, 0.2])
    tether, speed, tensions, margins, spins = [], [], [], [], []
    for k, sp in enumerate(setpoints):
        w = _spin_about_y(radii, momentum_y)
        a = allocator.allocate(k * PERIOD_NS, sp, w)
        radii = np.array(allocator.radii_m)  # where the joints are at the next tick
        tether.append(a.joint_position[TETHER])
        speed.append(a.joint_velocity[TETHER])
        tensions.append(a.tension_n)
        margins.append(a.tension_margin_n)
        spins.append(w[1])
    tether, speed = np.array(tether), np.array(speed)
    tensions, spins = np.array(tensions), np.array(spins)
    np.testing.assert_allclose(tether[:-1] + speed[:-1] * DT, tether[1:], atol=1e-12)
    accel = np.diff(np.concatenate([[0.0], speed])) / DT  # the corner at each tick
    centripetal = m_h * tether / 2.0 * spins**2  # tension of a tether held still
    np.testing.assert_allclose(tensions, centripetal - m_h * accel / 2.0, atol=1e-6)
    # the margin paying out; reeling in, at most half the centripetal load (a slow spin
    # may be reeled in: the reel-in adds tension)
    reeling_in = np.concatenate([[False], np.diff(tether) < 0.0]) | (np.arange(len(tether)) >= 1500)
    required = np.where(reeling_in, np.minimum(margin, 0.5 * centripetal), margin)
    np.testing.assert_allclose(margins, tensions - required, atol=1e-9)
    # never slack; the requirement kept wherever the spin can hold it at all
    assert np.min(tensions) >= -1e-9
    assert np.all(tensions >= np.minimum(required, centripetal) - 1e-6)
    out_end = tether[1499]
    if out_end < 6.0 - 1e-9:  # stopped early: only because the spin no longer holds it
        r_end, w_end = (
            out_end / 2.0,
            momentum_y / principal_inertia(MODEL, [out_end / 2, 0.2, 0.2])[1],
        )
        assert m_h * r_end * w_end**2 <= margin * 1.05
        assert momentum_y < 150.0
    else:
        assert momentum_y > 10.0
    assert tether[-1] == pytest.approx(1.4, abs=1e-9)  # back in...
    assert np.min(tether[1500:]) >= 1.4 - 1e-9  # ...without overshooting
    reel_accel = MODEL.tether_acceleration_max_m_s2 * allocator.config.tether_acceleration_fraction
    if momentum_y == 150.0:  # fast spin: the reel's own limits bind, the full length is reached
        assert np.max(np.abs(speed)) == pytest.approx(MODEL.tether_speed_max_m_s, rel=1e-9)
        assert np.max(accel) == pytest.approx(reel_accel, rel=1e-9)
    if momentum_y == 10.0:  # slow spin: the taut bound, not the reel, limits the pay-out
        assert np.max(accel[:1500]) < 0.1 * reel_accel


def test_a_spin_too_slow_for_the_margin_is_reeled_in_taut() -> None:
    """Centripetal load 0.3 N under the 1 N margin: reeled in (it was held), never slack.

    A random tumble mostly about the tether has such a slow spin across it; reeling in
    is how its rate is raised (H_y conserved: the load grows as 1 / r_x^3).
    """
    m_h = hemi_mass_kg(MODEL)
    start = np.array([2.8, 0.2, 0.2])
    w_y0 = math.sqrt(0.3 / (m_h * 2.8))  # [rad/s] centripetal load 0.3 N
    momentum_y = w_y0 * float(principal_inertia(MODEL, start)[1])
    allocator = TetherLimbAllocator(MODEL, AllocatorConfig(), initial_radii_m=start)
    assert allocator.config.tension_margin_n == 1.0
    target = principal_inertia(MODEL, [1.2, 0.2, 0.2])
    radii, tether, tensions, required = start, [], [], []
    for k in range(3000):
        a = allocator.allocate(k * PERIOD_NS, target, _spin_about_y(radii, momentum_y))
        radii = np.array(allocator.radii_m)
        tether.append(a.joint_position[TETHER])
        tensions.append(a.tension_n)
        required.append(a.required_tension_n)
    tether, tensions, required = np.array(tether), np.array(tensions), np.array(required)
    assert tether[-1] == pytest.approx(2.4, abs=1e-9)  # in, at the target...
    assert np.min(tether) >= 2.4 - 1e-9  # ...without overshooting it
    assert required[0] == pytest.approx(0.15, rel=1e-9)  # half the load, under the margin
    assert required[-1] == pytest.approx(1.0)  # spun up: the full margin again
    assert np.all(tensions >= required - 1e-6)  # the planned tension: taut throughout
    # paying out at that spin keeps the full margin: the tether is held
    out = TetherLimbAllocator(MODEL, AllocatorConfig(), initial_radii_m=start)
    for k in range(100):
        a = out.allocate(k * PERIOD_NS, principal_inertia(MODEL, [3.0, 0.2, 0.2]), [0, w_y0, 0])
    assert a.joint_position[TETHER] == pytest.approx(5.6, abs=1e-12)
    assert a.required_tension_n == 1.0


def _reel_in_ramp(
    window_s: float, stop_radius_m: float, supported: bool = False
) -> dict[str, np.ndarray]:
    """The 0.3 N spin of the test above, the setpoint moving in at 0.25 m/s (r_x) until
    ``stop_radius_m``, then resting there: a plan played back tick by tick (``supported``:
    with the feet on the ground)."""
    m_h = hemi_mass_kg(MODEL)
    start = np.array([2.8, 0.2, 0.2])
    w_y0 = math.sqrt(0.3 / (m_h * 2.8))
    momentum_y = w_y0 * float(principal_inertia(MODEL, start)[1])
    config = AllocatorConfig(reference_velocity_window_s=window_s)
    allocator = TetherLimbAllocator(MODEL, config, initial_radii_m=start)
    radii, out = start, {"tether": [], "tension": [], "required": [], "reference": []}
    for k in range(1500):
        r_ref = max(stop_radius_m, 2.8 - 0.25 * k * DT)
        a = allocator.allocate(
            k * PERIOD_NS,
            principal_inertia(MODEL, [r_ref, 0.2, 0.2]),
            _spin_about_y(radii, momentum_y),
            supported=supported,
        )
        radii = np.array(allocator.radii_m)
        out["tether"].append(a.joint_position[TETHER])
        out["tension"].append(a.tension_n)
        out["required"].append(a.required_tension_n)
        out["reference"].append(2.0 * r_ref)
    return {key: np.array(value) for key, value in out.items()}


def test_a_moving_setpoint_is_followed_at_its_speed_taut() -> None:
    """A slow spin's reel-in planned at 0.25 m/s is followed at that speed, never slack.

    Without the setpoint's velocity the reel approached each 10 ms setpoint as if the
    plan stopped there, which the slow spin can only brake taut from a crawl.
    """
    followed = _reel_in_ramp(0.1, 1.6)
    crawling = _reel_in_ramp(0.0, 1.6)
    t_half = 0.5 * (2.8 - 1.6) / 0.25  # [s] half-way down the 4.8 s ramp
    k = round(t_half / DT)
    lag_followed = followed["tether"][k] - followed["reference"][k]
    lag_crawling = crawling["tether"][k] - crawling["reference"][k]
    assert lag_followed < 0.1  # [m] of tether length, half-way down the ramp
    assert lag_crawling > 3.0 * lag_followed
    # time to reach 1.7 m of r_x (3.4 m of tether): the ramp's 4.4 s against a crawl
    reached_followed = np.argmax(followed["tether"] <= 3.4) * DT
    reached_crawling = np.argmax(crawling["tether"] <= 3.4) * DT
    assert reached_followed < 5.0
    assert reached_crawling > 1.3 * reached_followed or crawling["tether"].min() > 3.4
    for run in (followed, crawling):
        assert np.all(run["tension"][1:] >= run["required"][1:] - 1e-6)  # taut throughout


def test_a_plan_stopping_faster_than_the_spin_can_brake_is_overshot_taut() -> None:
    """The reel-in stops at 1.6 m abruptly: braked taut, so past it, then back, never slack."""
    run = _reel_in_ramp(0.1, 1.6)
    tether = run["tether"]
    assert np.min(tether) < 3.2 - 1e-3  # overshot the stop...
    assert np.min(tether) > MODEL.tether_length_min_m  # ...before the reel's end
    assert tether[-1] == pytest.approx(3.2, abs=1e-6)  # and back on it
    assert np.all(run["tension"][1:] >= run["required"][1:] - 1e-6)


def test_held_by_its_feet_the_reel_brakes_at_its_own_limit() -> None:
    """The same abrupt stop with the robot on the ground: the reel stops within its own
    braking distance, and no free-fall tension is claimed.

    In free fall the slow spin cannot brake the reel-in taut, so it coasts past the stop
    (above); on the ground that coast dragged the hemis together after a landing.
    """
    free = _reel_in_ramp(0.1, 1.6)
    held = _reel_in_ramp(0.1, 1.6, supported=True)
    speed = 2.0 * 0.25  # [m/s] of tether length, the ramp's
    deceleration = 0.9 * MODEL.tether_acceleration_max_m_s2  # [m/s^2] the configured share
    braking_m = speed**2 / (2.0 * deceleration)  # [m] a stop at the reel's limit
    overshoot_free = 3.2 - float(np.min(free["tether"]))
    overshoot_held = 3.2 - float(np.min(held["tether"]))
    assert overshoot_held <= braking_m + 0.01  # [m] a tick of lag at most
    assert overshoot_free > 5.0 * max(overshoot_held, braking_m)
    assert held["tether"][-1] == pytest.approx(3.2, abs=1e-6)
    assert np.all(np.isnan(held["tension"])) and np.all(np.isnan(held["required"]))


def test_without_spin_the_tether_is_never_paid_out() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=[1.5, 0.2, 0.2])
    allocations = _run(
        allocator, np.array([principal_inertia(MODEL, [2.5, 0.3, 0.3])] * 100), [1.0, 0.0, 0.0]
    )
    tether = [a.joint_position[TETHER] for a in allocations]
    assert max(tether) == pytest.approx(3.0, abs=1e-12)
    assert allocations[-1].radii_m[1] == pytest.approx(0.3)  # the limbs still move
    assert allocations[-1].rate_limited


def test_deterministic_and_same_stamp_replaces_the_tick() -> None:
    setpoints = _random_walk_setpoints(5, 200)
    runs = [
        _run(
            TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M), setpoints, [0, 1, 0]
        )
        for _ in range(2)
    ]
    for a, b in zip(*runs, strict=True):
        assert np.array_equal(a.joint_position, b.joint_position)
        assert np.array_equal(a.joint_velocity, b.joint_velocity)
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    first = allocator.allocate(0, setpoints[0], [0, 1, 0])
    allocator.allocate(0, principal_inertia(MODEL, [1.0, 0.15, 0.35]), [0, 1, 0])
    again = allocator.allocate(0, setpoints[0], [0, 1, 0])
    assert np.array_equal(first.joint_position, again.joint_position)
    with pytest.raises(ValueError, match="earlier"):
        allocator.allocate(-PERIOD_NS, setpoints[0], [0, 1, 0])


@pytest.mark.parametrize(
    ("setpoint", "w"),
    [
        ([math.nan, 1.0, 1.0], None),
        ([1.0, 2.0, math.inf], None),
        ([1.0, 150.0, 150.0], [0, math.nan, 0]),
    ],
)
def test_bad_input_raises_and_leaves_state_unchanged(setpoint: list[float], w: object) -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    reference = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    good = principal_inertia(MODEL, [2.0, 0.3, 0.3])
    allocator.allocate(0, good, [0, 1, 0])
    reference.allocate(0, good, [0, 1, 0])
    with pytest.raises(ValueError):
        allocator.allocate(PERIOD_NS, setpoint, w)  # type: ignore[arg-type]
    a = allocator.allocate(PERIOD_NS, good, [0, 1, 0])
    b = reference.allocate(PERIOD_NS, good, [0, 1, 0])
    assert np.array_equal(a.joint_position, b.joint_position)


def test_tension_is_nan_only_without_angular_velocity() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=PAPER_INITIAL_RADII_M)
    a = allocator.allocate(0, principal_inertia(MODEL, PAPER_INITIAL_RADII_M))
    assert math.isnan(a.tension_n)
    b = allocator.allocate(PERIOD_NS, principal_inertia(MODEL, PAPER_INITIAL_RADII_M), [0, 1, 0])
    assert b.tension_n == pytest.approx(hemi_mass_kg(MODEL) * 2.8)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"control_period_s": 0.0},
        {"control_period_s": math.nan},
        {"tension_margin_n": -1.0},
        {"tension_margin_n": 0.0},
        {"speed_fraction": 1.5},
        {"limb_acceleration_fraction": 0.0},
        {"tether_acceleration_fraction": 1.01},
        {"reference_velocity_window_s": -0.1},
        {"reference_velocity_window_s": math.inf},
        {"supported_specific_force_m_s2": 0.0},
        {"supported_specific_force_m_s2": math.nan},
        {"supported_dwell_s": -0.1},
    ],
)
def test_config_is_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        AllocatorConfig(**kwargs)


def test_initial_radii_are_validated() -> None:
    with pytest.raises(ValueError, match="initial_radii_m"):
        TetherLimbAllocator(MODEL, initial_radii_m=[5.0, 0.2, 0.2])
    with pytest.raises(ValueError, match="initial_radii_m"):
        TetherLimbAllocator(MODEL, initial_radii_m=[2.0, math.nan, 0.2])
