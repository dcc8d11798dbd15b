"""Equations of motion of the morphing ten-mass body (paper section V, DESIGN.md section 3).

State (14 plain floats, see :data:`STATE_SIZE`):
``p`` (3) COM position, world [m]; ``v`` (3) COM velocity, world [m/s];
``q`` (4) attitude quaternion world <- base, scalar first; ``L`` (3) angular
momentum about the COM in body coordinates [kg m^2/s]; ``W`` the actuator work
done so far [J] (integrated alongside so it has the integrator's accuracy).

Rotation, body frame, with the shape moving relative to the body::

    L = I w + h,         h = sum m_i r_i x dr_i   (relative angular momentum)
    dL/dt + w x L = tau                           (= d/dt(I w + h) + w x (I w + h))

Carrying ``L`` rather than ``w`` makes the derivative need only ``I`` and ``h``
at the stage time; ``w = I^-1 (L - h)``. In torque-free flight the world-frame
momentum ``R L`` is then constant and the gyroscopic term ``- w x L`` keeps
``|L|`` fixed. ``gyroscopic_sign = +1`` flips it (the sign error of the paper's
discrete MPC model): tests use it to show that a world-H check catches the error.

Translation: ``M dv/dt = F - B v - M g`` (paper eq. "linear").

Actuator power (rate of work of the morphing actuators on the system, the
internal forces times the masses' velocities relative to the body)::

    P = dw/dt . h - 1/2 w' (dI/dt) w + d/dt(1/2 sum m |dr|^2) - sum f_ext_i . dr_i

so that the kinetic energy about the COM, ``T = 1/2 w'Iw + w.h + 1/2 sum m|dr|^2``,
obeys ``dT/dt = P + (power of external forces about the COM)``. With ``h = 0``
this is the DESIGN.md formula ``dE/dt = w.tau - 1/2 w'(dI/dt)w``. Gyroscopic
forces do no work (``w . (w x L) = 0``), so the energy balance holds whatever
the gyroscopic sign: only world-frame angular momentum detects that error.

:func:`state_derivative` and :func:`rk4_step` are the one description of these equations:
the compiled kernels (:mod:`.kernels`) build their graph by calling them with CasADi
symbols (only arithmetic, the square root passed in; :func:`external_load` skips
the masses off the ground with floats and selects with symbols).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from splitter_model.rotations import quaternion_to_matrix_entries as rotation_matrix
from splitter_sim.core.contact import ground_contact_force

STATE_SIZE = 14
P, V, Q, L, WORK = slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13), 13


class DynamicsParameters:
    """Constants and step-wise inputs of the derivative (plain attributes, set by the simulator)."""

    __slots__ = (
        "contact",
        "contact_damping",
        "contact_stiffness",
        "damping",
        "friction_coefficient",
        "friction_damping",
        "gravity",
        "ground_planes",
        "gyroscopic_sign",
        "thrust",
        "total_mass",
    )

    def __init__(
        self,
        *,
        total_mass: float,
        damping: float,
        gravity: float,
        contact_stiffness: float,
        contact_damping: float,
        friction_coefficient: float,
        friction_damping: float,
        gyroscopic_sign: float = -1.0,
    ) -> None:
        self.total_mass = total_mass  # [kg]
        self.damping = damping  # B [N s/m]
        self.gravity = gravity  # [m/s^2] along -z
        self.contact_stiffness = contact_stiffness  # [N/m]
        self.contact_damping = contact_damping  # [N s/m]
        self.friction_coefficient = friction_coefficient  # [-]
        self.friction_damping = friction_damping  # [N s/m]
        self.gyroscopic_sign = gyroscopic_sign  # -1: dL/dt = tau - w x L (physics)
        # Masses that may touch the ground within this step (empty: no contact checks).
        self.contact: tuple[int, ...] = ()
        # Jump thrust for this step: tuples (mass index, fx, fy, fz) world [N].
        self.thrust: tuple[tuple[int, float, float, float], ...] = ()
        # The ground plane (nx, ny, nz, d) each mass touches (splitter_model.terrain);
        # None: the level plane z = 0 for every mass.
        self.ground_planes: Sequence[Sequence[Any]] | None = None


def angular_velocity(shape: Any, lx: Any, ly: Any, lz: Any) -> tuple[Any, Any, Any]:
    """w = I^-1 (L - h), body frame [rad/s] (floats or symbols)."""
    a, b, c, d, e, f = shape.inertia_inv
    hx, hy, hz = shape.h
    x, y, z = lx - hx, ly - hy, lz - hz
    return a * x + d * y + e * z, d * x + b * y + f * z, e * x + f * y + c * z


def state_derivative(
    s: Sequence[Any],
    shape: Any,
    prm: Any,
    out: dict | None = None,
    external: Callable[..., tuple[Any, ...]] | None = None,
) -> list[Any]:
    """Time derivative of the 14-float state with the shape at the same instant.

    ``out``, when given, receives the intermediate quantities (forces per mass,
    angular velocity and acceleration, rotation) for outputs: one code path for
    integration and reporting.

    The one description of the equations of motion: the compiled kernels call it
    with CasADi symbols, ``shape`` and ``prm`` then being namespaces of the same
    attribute names and ``external`` their selection form of the external loads.
    ``external(s, w, shape, prm, out)`` returns the loads (as :func:`external_load`);
    None: the loads of ``prm.thrust`` and of the ground contacts of ``prm.contact``
    (``out`` then also receives the rotation and the contacts (i, fx, fy, fz, height)).
    """
    vx, vy, vz, qw, qx, qy, qz, lx, ly, lz = s[3:13]
    ia, ib, ic, i_d, ie, i_f = shape.inertia_inv
    hx, hy, hz = shape.h
    ex, ey, ez = lx - hx, ly - hy, lz - hz
    wx = ia * ex + i_d * ey + ie * ez  # w = I^-1 (L - h)
    wy = i_d * ex + ib * ey + i_f * ez
    wz = ie * ex + i_f * ey + ic * ez
    if external is not None:
        fx, fy, fz, tx, ty, tz, p_rel = external(s, (wx, wy, wz), shape, prm, out)
    elif prm.thrust or prm.contact or out is not None:
        r = rotation_matrix(qw, qx, qy, qz)
        if not shape.relative_ready:
            shape.relative()
        forces = [] if out is not None else None
        fx, fy, fz, tx, ty, tz, p_rel = external_load(
            s, (wx, wy, wz), r, shape, prm, ground_contact_force, forces
        )
        if out is not None:
            out["rotation"] = r
            out["contacts"] = forces
    else:
        fx = fy = fz = tx = ty = tz = p_rel = 0.0
    m_inv = 1.0 / prm.total_mass
    b = prm.damping
    ax = (fx - b * vx) * m_inv
    ay = (fy - b * vy) * m_inv
    az = (fz - b * vz) * m_inv - prm.gravity
    g = prm.gyroscopic_sign
    dlx = tx + g * (wy * lz - wz * ly)
    dly = ty + g * (wz * lx - wx * lz)
    dlz = tz + g * (wx * ly - wy * lx)
    if shape.moving or out is not None:
        # dw/dt = I^-1 (dL/dt - (dI/dt) w - dh/dt)
        ia, ib, ic, i_d, ie, i_f = shape.inertia_dot
        hdx, hdy, hdz = shape.h_dot
        ex = dlx - (ia * wx + i_d * wy + ie * wz) - hdx
        ey = dly - (i_d * wx + ib * wy + i_f * wz) - hdy
        ez = dlz - (ie * wx + i_f * wy + ic * wz) - hdz
        awx, awy, awz = symmetric_product(shape.inertia_inv, ex, ey, ez)
        w_idot_w = (
            ia * wx * wx
            + ib * wy * wy
            + ic * wz * wz
            + 2.0 * (i_d * wx * wy + ie * wx * wz + i_f * wy * wz)
        )
        power = (
            awx * hx
            + awy * hy
            + awz * hz
            - 0.5 * w_idot_w
            + shape.kinetic_energy_relative_dot
            - p_rel
        )
        if out is not None:
            out["angular_velocity"] = (wx, wy, wz)
            out["angular_acceleration"] = (awx, awy, awz)
            out["force_world"] = (fx, fy, fz)
            out["torque_body"] = (tx, ty, tz)
            out["acceleration_world"] = (ax, ay, az)
            out["actuator_power"] = power
    else:
        power = 0.0
    return [
        vx,
        vy,
        vz,
        ax,
        ay,
        az,
        -0.5 * (qx * wx + qy * wy + qz * wz),
        0.5 * (qw * wx + qy * wz - qz * wy),
        0.5 * (qw * wy + qz * wx - qx * wz),
        0.5 * (qw * wz + qx * wy - qy * wx),
        dlx,
        dly,
        dlz,
        power,
    ]


# --- formulas written once for floats and CasADi symbols (the compiled kernels) ---------
def symmetric_product(m: Sequence[Any], x: Any, y: Any, z: Any) -> tuple[Any, Any, Any]:
    """``M (x, y, z)`` of a symmetric 3x3 matrix given as (xx, yy, zz, xy, xz, yz)."""
    a, b, c, d, e, f = m
    return a * x + d * y + e * z, d * x + b * y + f * z, e * x + f * y + c * z


def external_load(  # noqa: PLR0917  (hot path: positional)
    s: Sequence[Any],
    w: Sequence[Any],
    r: Sequence[Any],
    shape: Any,
    prm: Any,
    law: Callable[..., tuple[Any, Any, Any]],
    forces: list | None = None,
    select: Callable[..., tuple[Any, Any, Any]] | None = None,
) -> tuple[Any, ...]:
    """Force (world), torque about the COM (body) and power on the relative motion.

    ``prm.thrust``: external forces (i, gx, gy, gz) on mass i, world [N]; then the
    ground force ``law(height, vx, vy, vz, k, c, mu, c_t, nx, ny, nz)`` (``prm``'s
    contact stiffness, damping, friction coefficient and slope; ``height`` the signed
    distance to the mass's plane of ``prm.ground_planes``, normal ``n``) on each mass
    of ``prm.contact`` (``shape.rx`` ... ``shape.vz``, rotation ``r``, state ``s``,
    angular velocity ``w``). With floats (``select`` None) only the masses below
    the ground that the ground pushes count (and go to ``forces`` as (i, fx, fy,
    fz, height)); with symbols every mass's force goes through ``select(i, gx, gy,
    gz)``. Returns (fx, fy, fz, tx, ty, tz, p_rel), summed in that order.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    wx, wy, wz = w
    pz, vx, vy, vz = s[2], s[3], s[4], s[5]
    thrust, contact = prm.thrust, prm.contact
    k, c = prm.contact_stiffness, prm.contact_damping
    mu, ct = prm.friction_coefficient, prm.friction_damping
    planes = prm.ground_planes
    nx, ny, nz = 0.0, 0.0, 1.0
    rx, ry, rz, dvx, dvy, dvz = shape.rx, shape.ry, shape.rz, shape.vx, shape.vy, shape.vz
    fx = fy = fz = 0.0  # external non-gravity force, world [N]
    tx = ty = tz = 0.0  # external torque about the COM, body [N m]
    p_rel = 0.0  # power of external forces on the relative motion [W]
    n_thrust = len(thrust)
    for n, term in enumerate((*thrust, *contact) if n_thrust else contact):
        if n < n_thrust:
            i, gx, gy, gz = term
            x, y, z, dx, dy, dz = rx[i], ry[i], rz[i], dvx[i], dvy[i], dvz[i]
        else:
            x, y, z = rx[term], ry[term], rz[term]
            height = pz + r20 * x + r21 * y + r22 * z
            if planes is not None:  # signed distance to the mass's plane
                nx, ny, nz, d = planes[term]
                height = (
                    nx * (s[0] + r00 * x + r01 * y + r02 * z)
                    + ny * (s[1] + r10 * x + r11 * y + r12 * z)
                    + nz * height
                    - d
                )
            if select is None and height >= 0.0:
                continue
            dx, dy, dz = dvx[term], dvy[term], dvz[term]
            # velocity of the mass: v + R (w x r + dr)
            ux = wy * z - wz * y + dx
            uy = wz * x - wx * z + dy
            uz = wx * y - wy * x + dz
            mvx = vx + r00 * ux + r01 * uy + r02 * uz
            mvy = vy + r10 * ux + r11 * uy + r12 * uz
            mvz = vz + r20 * ux + r21 * uy + r22 * uz
            gx, gy, gz = law(height, mvx, mvy, mvz, k, c, mu, ct, nx, ny, nz)
            if select is not None:
                gx, gy, gz = select(term, gx, gy, gz)
            elif gx == 0.0 and gy == 0.0 and gz == 0.0:
                continue
            elif forces is not None:
                forces.append((term, gx, gy, gz, height))
        bx = r00 * gx + r10 * gy + r20 * gz
        by = r01 * gx + r11 * gy + r21 * gz
        bz = r02 * gx + r12 * gy + r22 * gz
        fx += gx
        fy += gy
        fz += gz
        tx += y * bz - z * by
        ty += z * bx - x * bz
        tz += x * by - y * bx
        p_rel += bx * dx + by * dy + bz * dz
    return fx, fy, fz, tx, ty, tz, p_rel


def rk4_step(  # noqa: PLR0917  (hot path: positional)
    s: Sequence[Any],
    h: Any,
    prm: Any,
    shape_start: Any,
    shape_mid: Any,
    shape_end: Any,
    sqrt: Callable[[Any], Any] = math.sqrt,
    external: Callable[..., tuple[Any, ...]] | None = None,
) -> list[Any]:
    """One classical RK4 step of length ``h``; the shape is known at the three stage times.

    The quaternion is renormalised after the step (unit norm kept exactly). ``sqrt``
    and ``external`` (as for :func:`state_derivative`): the kernels' symbolic forms.
    """
    f = state_derivative
    half = 0.5 * h
    k1 = f(s, shape_start, prm, None, external)
    k2 = f([a + half * b for a, b in zip(s, k1, strict=True)], shape_mid, prm, None, external)
    k3 = f([a + half * b for a, b in zip(s, k2, strict=True)], shape_mid, prm, None, external)
    k4 = f([a + h * b for a, b in zip(s, k3, strict=True)], shape_end, prm, None, external)
    sixth = h / 6.0
    out = [
        a + sixth * (b1 + 2.0 * (b2 + b3) + b4)
        for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4, strict=True)
    ]
    n = 1.0 / sqrt(out[6] * out[6] + out[7] * out[7] + out[8] * out[8] + out[9] * out[9])
    out[6] *= n
    out[7] *= n
    out[8] *= n
    out[9] *= n
    return out
