"""The compiled kernels (:mod:`splitter_sim.core.kernels`) against the pure-Python code.

The kernels are generated from the Python formulas themselves (called with CasADi
symbols), operation by operation, so every quantity agrees to round-off (1e-12
relative here; in practice a few ulp), and whole runs of the simulator agree to
round-off as well.
"""

from __future__ import annotations

import inspect
import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_model import codegen
from splitter_model.actuators import actuator_limits
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import GRAVITY_PRESETS, RobotModel
from splitter_sim import bench
from splitter_sim.core import actuators, kernels
from splitter_sim.core.rigid_body import DynamicsParameters, rk4_step
from splitter_sim.core.shape import Shape, ShapeKinematics
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
LIMITS = actuator_limits(MODEL)
KIN = ShapeKinematics(MODEL)
DT = 0.005  # [s]
SHAPE_FIELDS = (
    "inertia",
    "inertia_inv",
    "inertia_dot",
    "h",
    "h_dot",
    "kinetic_energy_relative",
    "kinetic_energy_relative_dot",
    "com_geometric",
    "radius_max",
    "speed_max",
    "rx",
    "ry",
    "rz",
    "vx",
    "vy",
    "vz",
    "ax",
    "ay",
    "az",
)


@pytest.fixture(scope="module")
def library() -> object:
    lib = kernels.load_library()
    if lib is None:
        pytest.skip("no C compiler and no cached simulator kernels")
    return lib


def _parameters(gravity: float = GRAVITY_PRESETS["moon"]) -> DynamicsParameters:
    return DynamicsParameters(
        total_mass=KIN.total_mass,
        damping=MODEL.damping_coefficient,
        gravity=gravity,
        contact_stiffness=5.0e4,
        contact_damping=1.0e3,
        friction_coefficient=0.8,
        friction_damping=1.0e3,
    )


def _kernels(library: object, prm: DynamicsParameters) -> kernels.Kernels:
    return kernels.Kernels(library, MODEL, KIN.masses, LIMITS, prm, DT)  # type: ignore[arg-type]


def _assert_close(actual: object, expected: object, what: str, rtol: float = 1e-12) -> None:
    a = np.asarray(actual, dtype=float)
    e = np.asarray(expected, dtype=float)
    scale = max(1.0, float(np.abs(e).max()))
    error = float(np.abs(a - e).max()) / scale
    assert error <= rtol, f"{what}: relative error {error:.3g}"


def _assert_shapes_equal(compiled: Shape, python: Shape) -> None:
    python.relative()
    assert compiled.moving == python.moving
    for name in SHAPE_FIELDS:
        _assert_close(getattr(compiled, name), getattr(python, name), name)


def _joint_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q = rng.uniform(LIMITS.position_min, LIMITS.position_max)
    return q, rng.normal(0.0, 2.0, 25), rng.normal(0.0, 20.0, 25)


def _random_case(
    library: object, seed: int, prm: DynamicsParameters | None = None
) -> tuple[np.random.Generator, kernels.Kernels, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The generator of ``seed``, the kernels and a joint state (q, qd, qdd) drawn from it."""
    rng = np.random.default_rng(seed)
    return rng, _kernels(library, prm or _parameters()), _joint_state(rng)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_compiled_shape_equals_the_python_shape(library: object, seed: int) -> None:
    _, kern, (q, qd, qdd) = _random_case(library, seed)
    _assert_shapes_equal(
        kern.evaluate(q, qd, qdd), KIN.evaluate(q.tolist(), qd.tolist(), qdd.tolist())
    )
    _assert_shapes_equal(kern.evaluate(q), KIN.evaluate(q.tolist()))  # at rest
    qdd[:] = 0.0  # moving at constant speed
    _assert_shapes_equal(kern.evaluate(q, qd, qdd), KIN.evaluate(q.tolist(), qd.tolist()))


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_compiled_servo_equals_the_python_servo(library: object, seed: int) -> None:
    rng, kern, (q, qd, _) = _random_case(library, seed)
    qd = np.clip(0.2 * qd, -LIMITS.speed_max, LIMITS.speed_max)
    # Far targets, targets within a step (deadbeat), moving and resting targets.
    target = np.where(rng.random(25) < 0.5, q + rng.normal(0.0, 1e-3, 25), _joint_state(rng)[0])
    target_v = np.where(rng.random(25) < 0.5, 0.0, rng.normal(0.0, 1.0, 25))
    kern.ws[kernels.WS_Q] = q
    kern.ws[kernels.WS_QD] = qd
    kern.ws[kernels.WS_TARGET] = target
    kern.ws[kernels.WS_TARGET_V] = target_v
    kern.begin()
    expected = actuators.servo_acceleration(q, qd, target, target_v, LIMITS, DT)
    qdd = kern.out_begin[kernels.BEGIN_QDD]
    np.testing.assert_allclose(qdd, expected, rtol=1e-12, atol=1e-9)
    assert bool(kern.out_begin[kernels.BEGIN_MOVING]) == bool(qd.any() or expected.any())
    _assert_shapes_equal(
        kernels.shape_from_block(kern.out_begin[kernels.BEGIN_SHAPE :].tolist()),
        KIN.evaluate(q.tolist(), qd.tolist(), expected.tolist()),
    )


@pytest.mark.parametrize("moving", [True, False])
@pytest.mark.parametrize("seed", range(6))
def test_compiled_rk4_step_equals_python_with_contact_and_thrust(
    library: object, seed: int, moving: bool
) -> None:
    prm = _parameters()
    rng, kern, (q, qd, qdd) = _random_case(library, seed, prm)
    if not moving:  # held joints: at rest, or keeping the accelerations of the last step
        qd[:] = 0.0
        qdd *= seed % 2
    shape = KIN.evaluate(q.tolist(), qd.tolist(), qdd.tolist())
    quaternion = rng.normal(size=4)
    quaternion /= np.linalg.norm(quaternion)
    # Low enough that several masses are under the ground plane.
    s = [0.1, -0.2, 0.25, *rng.normal(0.0, 1.0, 3), *quaternion, *rng.normal(0.0, 5.0, 3), 2.0]
    prm.thrust = ((5, 30.0, -4.0, 80.0), (0, -2.0, 1.0, 12.0))
    prm.contact = tuple(i for i in range(10) if rng.random() < 0.8)
    h = DT / 2
    if moving:
        q_mid, qd_mid = actuators.advance(q, qd, qdd, 0.5 * h)
        q_end, qd_end = actuators.advance(q, qd, qdd, h)
        mid = KIN.evaluate(q_mid.tolist(), qd_mid.tolist(), qdd.tolist())
        end = KIN.evaluate(q_end.tolist(), qd_end.tolist(), qdd.tolist())
    else:
        mid = end = shape
    expected = rk4_step(s, h, prm, shape, mid, end)
    ws = kern.ws
    ws[kernels.WS_Q] = q
    ws[kernels.WS_QD] = qd
    ws[kernels.WS_QDD] = qdd
    ws[kernels.WS_STATE] = s
    ws[kernels.WS_H] = h
    ws[kernels.WS_JOINT_ADVANCE] = 1.0 if moving else 0.0
    kern.set_forces(prm.thrust, prm.contact)
    kern.step()
    out = kern.out_step
    _assert_close(out[kernels.STEP_STATE], expected, "state")
    assert abs(out[13] - expected[13]) <= 1e-12 * max(1.0, abs(expected[13]))  # actuator work
    if moving:
        np.testing.assert_array_equal(out[kernels.STEP_Q], q_end)
        np.testing.assert_array_equal(out[kernels.STEP_QD], qd_end)
    # Without forces the flight kernel equals the Python step with no thrust nor contact.
    prm.thrust, prm.contact = (), ()
    kern.set_forces((), ())
    kern.flight()
    _assert_close(out[kernels.STEP_STATE], rk4_step(s, h, prm, shape, mid, end), "flight")


def _lunar_run(compiled: bool, steps: int, legs: bool) -> tuple[Simulator, list]:
    """The benchmark's run: a drop, two jumps, contact, sliding, morphing all along."""
    sim = Simulator(
        MODEL,
        SimConfig(gravity_m_s2=GRAVITY_PRESETS["moon"], compliant_legs=legs),
        InitialState(position_m=(0.0, 0.0, 0.8 if legs else 0.45)),
        compiled=compiled,
    )
    samples = []
    for k in range(steps):
        t = k * DT
        if k % bench.CONTROL_PERIOD_STEPS == 0:
            sim.command_joints(bench._morph_command(MODEL, t))
        thrust = any(t0 <= t < t1 for t0, t1 in bench.JUMPS)
        sim.command_jump_force(bench.JUMP_FORCE_N if thrust else (0.0, 0.0, 0.0))
        sim.step()
        if k % 25 == 0:
            samples.append(sim.state())
    return sim, samples


@pytest.mark.parametrize("legs", [False, True], ids=["lumped_feet", "compliant_legs"])
def test_whole_lunar_run_agrees_with_the_pure_python_simulator(library: object, legs: bool) -> None:
    steps = round(bench.DURATION_S / DT)
    fast, fast_states = _lunar_run(True, steps, legs)
    slow, slow_states = _lunar_run(False, steps, legs)
    assert fast.compiled
    assert not slow.compiled
    assert fast.contact_step_count == slow.contact_step_count
    assert legs or fast.contact_step_count > 0
    for a, b in zip(fast_states, slow_states, strict=True):
        np.testing.assert_allclose(a.position_m, b.position_m, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(a.orientation_wxyz, b.orientation_wxyz, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(a.joint_position, b.joint_position, rtol=0.0, atol=1e-12)
        np.testing.assert_array_equal(a.in_contact, b.in_contact)
        np.testing.assert_array_equal(a.in_thrust_range, b.in_thrust_range)
        assert a.actuator_work_j == pytest.approx(b.actuator_work_j, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize(
    "hemi_inertia", [(0.0, 0.0, 0.0), (0.03, 0.045, 0.04)], ids=["point bodies", "hemi inertia"]
)
def test_morphing_flight_agrees_with_the_pure_python_simulator(
    library: object, hemi_inertia: tuple[float, float, float]
) -> None:
    runs = []
    for compiled in (True, False):
        sim = Simulator(
            MODEL,
            SimConfig(ground_contact=False),
            InitialState(position_m=(0.0, 0.0, 10.0), angular_velocity_rad_s=(-0.3, -0.9, 0.9)),
            compiled=compiled,
            hemi_inertia_kg_m2=hemi_inertia,
        )
        sim.command_joints(joint_positions_from_radii(MODEL, (2.3, 0.3, 0.13)))
        states = []
        for k in range(600):
            if k == 280:
                sim.command_joints(joint_positions_from_radii(MODEL, (2.6, 0.16, 0.26)))
            sim.step()
            states.append(sim.state())
        runs.append(states)
    for a, b in zip(*runs, strict=True):
        np.testing.assert_allclose(a.angular_momentum_world, b.angular_momentum_world, atol=1e-10)
        np.testing.assert_allclose(a.angular_velocity_rad_s, b.angular_velocity_rad_s, atol=1e-10)
        np.testing.assert_allclose(a.inertia_tensor_kg_m2, b.inertia_tensor_kg_m2, atol=1e-12)
        np.testing.assert_array_equal(a.joint_position, b.joint_position)
        assert a.actuator_power_w == pytest.approx(b.actuator_power_w, rel=1e-9, abs=1e-9)


def test_without_a_compiler_the_simulator_runs_pure_python_with_a_warning(
    tmp_path: object, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.delenv(kernels.ENV_SWITCH, raising=False)
    monkeypatch.setattr(codegen, "compiler_available", lambda compiler="gcc": False)
    monkeypatch.setenv("SPLITTER_CACHE_DIR", str(tmp_path))  # an empty cache
    monkeypatch.setattr(kernels, "_LIBRARY", {})
    with caplog.at_level(logging.WARNING, logger="splitter_sim.core.kernels"):
        sim = Simulator(MODEL, SimConfig(), InitialState(position_m=(0.0, 0.0, 10.0)))
    assert not sim.compiled
    assert "pure-Python" in caplog.text
    sim.command_joints(joint_positions_from_radii(MODEL, (2.5, 0.25, 0.2)))
    for _ in range(20):
        sim.step()
    assert sim.state().is_finite()


def test_the_environment_switch_selects_pure_python(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(kernels.ENV_SWITCH, "0")
    assert kernels.load_library() is None
    assert not Simulator(MODEL, SimConfig(), InitialState()).compiled


def test_the_cached_library_is_named_by_every_module_its_graph_is_made_of(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    names = {module.__name__ for module in kernels.fingerprint_modules()}
    assert {
        "splitter_model.rotations",
        "splitter_sim.core.shape",
        "splitter_sim.core.rigid_body",
        "splitter_sim.core.actuators",
        "splitter_sim.core.kernels",
    } <= names
    before = kernels._fingerprint()
    source = inspect.getsource
    edited = "splitter_model.rotations"
    monkeypatch.setattr(
        inspect,
        "getsource",
        lambda module: source(module) + ("#" if module.__name__ == edited else ""),
    )
    assert kernels._fingerprint() != before  # a change of a shared formula rebuilds the C
