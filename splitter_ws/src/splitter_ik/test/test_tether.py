"""Tether tension while reeling, against Newton's law on the lumped masses in an inertial frame."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_ik.core.tether import (
    hemi_mass_kg,
    max_taut_radius_acceleration,
    reeling_tether_tension,
)
from splitter_model.model import (
    RobotModel,
    principal_inertia,
    tether_tension,
    tether_tension_3d,
)

MODEL = RobotModel()


def _inertial_hemi_positions(t: np.ndarray, h_z: float, r_x, r_y: float, r_z: float):
    """Masses of hemi a in the inertial frame: torque-free spin about z while reeling.

    Angular momentum about z is conserved, so the spin rate is H / Izz(r_x(t)); the
    spin angle is integrated numerically. Returns (n, 5, 3) positions.
    """
    rx = r_x(t)
    izz = principal_inertia(MODEL, np.stack([rx, np.full_like(rx, r_y), np.full_like(rx, r_z)], 1))[
        :, 2
    ]
    omega = h_z / izz
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t))])
    c, s = np.cos(theta), np.sin(theta)
    body = [
        (0.0, 0.0, 0.0),
        (0.0, r_y, 0.0),
        (0.0, -r_y, 0.0),
        (0.0, 0.0, r_z),
        (0.0, 0.0, -r_z),
    ]
    out = np.empty((len(t), 5, 3))
    for i, (_, y, z) in enumerate(body):
        x_b = rx
        out[:, i, 0] = c * x_b - s * y
        out[:, i, 1] = s * x_b + c * y
        out[:, i, 2] = z
    return out, omega


def test_tension_equals_newtons_law_on_the_hemi_masses() -> None:
    dt = 1e-5
    t = np.arange(0.0, 1.0, dt)
    r_x = lambda tt: 2.0 + 0.3 * np.sin(2.0 * tt)  # noqa: E731 (reeling profile [m])
    positions, omega = _inertial_hemi_positions(t, h_z=150.0, r_x=r_x, r_y=0.3, r_z=0.2)
    masses = np.array(
        [MODEL.body_mass_kg] + [MODEL.limb_mass_y_kg] * 2 + [MODEL.limb_mass_z_kg] * 2
    )
    acc = np.gradient(np.gradient(positions, t, axis=0), t, axis=0)
    force = np.einsum("i,kij->kj", masses, acc)  # total force on hemi a (only the tether)
    k = np.arange(1000, len(t) - 1000, 5000)
    for idx in k:
        # Tension is the radial part. In the rigid ten-mass model the hemi turns with the
        # tether, so the attachment also carries a tangential (Coriolis) force.
        direction = positions[idx, 0] / np.linalg.norm(positions[idx, 0])  # body from centre
        newton = -float(force[idx] @ direction)
        rx_ddot = -0.3 * 4.0 * np.sin(2.0 * t[idx])
        ours = reeling_tether_tension(MODEL, [0.0, 0.0, omega[idx]], float(r_x(t[idx])), rx_ddot)
        assert ours == pytest.approx(newton, rel=1e-4)


def test_static_spin_tension_is_the_hemi_mass_times_the_papers_expression() -> None:
    ours = reeling_tether_tension(MODEL, [0.0, 1.0, 0.0], 2.8)
    assert ours == pytest.approx(9.0 * 2.8)
    assert ours == pytest.approx(tether_tension_3d(MODEL, [0.3, 1.0, 0.0], 2.8))
    assert ours == pytest.approx(
        hemi_mass_kg(MODEL) / MODEL.body_mass_kg * tether_tension(MODEL, 1.0, 2.8)
    )


def test_taut_acceleration_bound_gives_exactly_the_margin() -> None:
    w = [0.4, 0.7, -0.5]
    a_max = max_taut_radius_acceleration(MODEL, w, 1.7, 2.0)
    assert reeling_tether_tension(MODEL, w, 1.7, a_max) == pytest.approx(2.0)
    # spin about the tether itself does not load it
    assert reeling_tether_tension(MODEL, [5.0, 0.0, 0.0], 1.7) == 0.0
