"""Shape of the morphing body: the ten lumped masses, their motion and the inertia tensor.

Given the 25 joint positions, velocities and accelerations, :func:`evaluate_shape`
returns, in the body frame ``base`` (origin at the centre of mass, x along the
tether), the positions ``r_i``, velocities ``dr_i`` and accelerations ``ddr_i``
of the ten masses relative to the centre of mass, and the quantities the
rotational dynamics needs: the inertia tensor about the centre of mass (products
included) and its inverse, the relative angular momentum ``h = sum m r x dr``,
its rate, ``dI/dt`` and the rate of the relative kinetic energy.

Positions are exactly those of :mod:`splitter_sim.core.kinematics`
(``limb_offsets_from_joint_positions`` + ``lumped_mass_positions``, then taken
relative to ``center_of_mass``; the unit tests assert it); the derivatives are
the analytic time derivatives of the same forward kinematics. This is the hot
path of the simulator, hence plain floats and the ``math`` module: numpy on
3-vectors costs microseconds per call.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from splitter_sim.core.kinematics import limb_frame
from splitter_sim.core.model import RobotModel

N_MASSES = 10
BODY_INDICES = (0, 5)  # hemi a body, hemi b body
HEMI_OF_MASS = (0, 0, 0, 0, 0, 1, 1, 1, 1, 1)


class Shape:
    """Mass distribution of the body at one instant (body frame, relative to the COM).

    Plain-float containers (lists of length 10 per axis, 6-tuples for symmetric
    tensors ``(xx, yy, zz, xy, xz, yz)``) so that the integrator's stages stay cheap.
    """

    __slots__ = (
        "ax",
        "ay",
        "az",
        "com_geometric",
        "h",
        "h_dot",
        "inertia",
        "inertia_dot",
        "inertia_inv",
        "kinetic_energy_relative",
        "kinetic_energy_relative_dot",
        "moving",
        "radius_max",
        "rx",
        "ry",
        "rz",
        "speed_max",
        "vx",
        "vy",
        "vz",
    )

    rx: list[float]
    ry: list[float]
    rz: list[float]
    vx: list[float]
    vy: list[float]
    vz: list[float]
    ax: list[float]
    ay: list[float]
    az: list[float]
    com_geometric: tuple[float, float, float]  # COM in the tether-midpoint frame [m]
    inertia: tuple[float, float, float, float, float, float]  # [kg m^2]
    inertia_inv: tuple[float, float, float, float, float, float]  # [1/(kg m^2)]
    inertia_dot: tuple[float, float, float, float, float, float]  # [kg m^2/s]
    h: tuple[float, float, float]  # sum m r x dr [kg m^2/s]
    h_dot: tuple[float, float, float]  # sum m r x ddr [N m]
    kinetic_energy_relative: float  # 1/2 sum m |dr|^2 [J]
    kinetic_energy_relative_dot: float  # sum m dr . ddr [W]
    moving: bool  # any mass moves relative to the body
    radius_max: float  # largest |r_i| [m]
    speed_max: float  # largest |dr_i| [m/s]

    def positions(self) -> NDArray[np.float64]:
        """Mass positions (10, 3) relative to the COM, body frame [m]."""
        return np.column_stack([self.rx, self.ry, self.rz])

    def velocities(self) -> NDArray[np.float64]:
        """Mass velocities (10, 3) relative to the body, body frame [m/s]."""
        return np.column_stack([self.vx, self.vy, self.vz])

    def accelerations(self) -> NDArray[np.float64]:
        """Mass accelerations (10, 3) relative to the body, body frame [m/s^2]."""
        return np.column_stack([self.ax, self.ay, self.az])

    def inertia_matrix(self) -> NDArray[np.float64]:
        """Inertia tensor (3, 3) about the COM, body frame [kg m^2]."""
        return sym_to_matrix(self.inertia)


def sym_to_matrix(s: Sequence[float]) -> NDArray[np.float64]:
    """(xx, yy, zz, xy, xz, yz) -> symmetric 3x3 matrix."""
    xx, yy, zz, xy, xz, yz = s
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def sym_inverse(s: Sequence[float]) -> tuple[float, float, float, float, float, float]:
    """Inverse of a symmetric positive-definite 3x3 matrix given as 6 entries."""
    xx, yy, zz, xy, xz, yz = s
    c_xx = yy * zz - yz * yz
    c_xy = xz * yz - xy * zz
    c_xz = xy * yz - xz * yy
    det = xx * c_xx + xy * c_xy + xz * c_xz
    if not det > 0.0:
        raise ValueError(f"inertia tensor is singular or not positive definite (det {det})")
    inv = 1.0 / det
    return (
        c_xx * inv,
        (xx * zz - xz * xz) * inv,
        (xx * yy - xy * xy) * inv,
        c_xy * inv,
        c_xz * inv,
        (xy * xz - xx * yz) * inv,
    )


class ShapeKinematics:
    """Precomputed constants of the ten-mass forward kinematics of one model."""

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self.l1 = model.thigh_length_m  # [m]
        self.l2 = model.shank_length_m  # [m]
        self.masses = tuple(float(m) for m in model.lumped_masses_kg)  # [kg]
        self.total_mass = float(sum(self.masses))  # [kg]
        # Limb frames (u, v, w) as plain tuples, order of names.LIMB_NAMES.
        self.frames = tuple(
            tuple(tuple(float(c) for c in row) for row in limb_frame(limb)) for limb in range(8)
        )

    def evaluate(
        self,
        q: Sequence[float],
        qd: Sequence[float] | None = None,
        qdd: Sequence[float] | None = None,
    ) -> Shape:
        """Shape for joint positions ``q`` (25), velocities ``qd`` and accelerations ``qdd``.

        ``qd``/``qdd`` of None mean the joints are at rest (no relative motion).
        """
        moving = qd is not None and (any(qd) or (qdd is not None and any(qdd)))
        if not moving:
            qd = qdd = None
        elif qdd is None:
            qdd = (0.0,) * 25
        l1, l2 = self.l1, self.l2
        masses = self.masses
        rx_half = 0.5 * q[24]
        # Geometric positions (tether-midpoint frame) and their derivatives.
        px = [rx_half, 0.0, 0.0, 0.0, 0.0, -rx_half, 0.0, 0.0, 0.0, 0.0]
        py = [0.0] * 10
        pz = [0.0] * 10
        vx = [0.0] * 10
        vy = [0.0] * 10
        vz = [0.0] * 10
        ax = [0.0] * 10
        ay = [0.0] * 10
        az = [0.0] * 10
        if moving:
            assert qd is not None and qdd is not None
            vb, ab = 0.5 * qd[24], 0.5 * qdd[24]
            vx[0], vx[5], ax[0], ax[5] = vb, -vb, ab, -ab
        for limb in range(8):
            k = 3 * limb
            q1, q2, q3 = q[k], q[k + 1], q[k + 2]
            (ux, uy, uz), (vvx, vvy, vvz), (wx, wy, wz) = self.frames[limb]
            c1, s1 = math.cos(q1), math.sin(q1)
            c2, s2 = math.cos(q2), math.sin(q2)
            c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
            p_u = l1 * c2 + l2 * c23
            p_p = l1 * s2 + l2 * s23
            # v_rot = cos q1 v + sin q1 w; w_rot = -sin q1 v + cos q1 w
            vrx, vry, vrz = c1 * vvx + s1 * wx, c1 * vvy + s1 * wy, c1 * vvz + s1 * wz
            i = limb + 1 + (limb // 4)  # mass index: 1..4 hemi a, 6..9 hemi b
            body = 0 if limb < 4 else 5
            px[i] = px[body] + p_u * ux + p_p * vrx
            py[i] = p_u * uy + p_p * vry
            pz[i] = p_u * uz + p_p * vrz
            if moving:
                assert qd is not None and qdd is not None
                d1, d2, d3 = qd[k], qd[k + 1], qd[k + 2]
                e1, e2, e3 = qdd[k], qdd[k + 1], qdd[k + 2]
                d23, e23 = d2 + d3, e2 + e3
                wrx, wry, wrz = -s1 * vvx + c1 * wx, -s1 * vvy + c1 * wy, -s1 * vvz + c1 * wz
                dp_u = -l1 * s2 * d2 - l2 * s23 * d23
                dp_p = l1 * c2 * d2 + l2 * c23 * d23
                ddp_u = -l1 * (c2 * d2 * d2 + s2 * e2) - l2 * (c23 * d23 * d23 + s23 * e23)
                ddp_p = l1 * (c2 * e2 - s2 * d2 * d2) + l2 * (c23 * e23 - s23 * d23 * d23)
                # p = p_u u + p_p v_rot;  d(v_rot)/dt = q1' w_rot;  d(w_rot)/dt = -q1' v_rot
                cw = p_p * d1
                vx[i] = vx[body] + dp_u * ux + dp_p * vrx + cw * wrx
                vy[i] = dp_u * uy + dp_p * vry + cw * wry
                vz[i] = dp_u * uz + dp_p * vrz + cw * wrz
                cw2 = 2.0 * dp_p * d1 + p_p * e1
                cv2 = ddp_p - p_p * d1 * d1
                ax[i] = ax[body] + ddp_u * ux + cv2 * vrx + cw2 * wrx
                ay[i] = ddp_u * uy + cv2 * vry + cw2 * wry
                az[i] = ddp_u * uz + cv2 * vrz + cw2 * wrz
        return self._about_com(masses, px, py, pz, vx, vy, vz, ax, ay, az, moving)

    def _about_com(  # noqa: PLR0917  (hot path)
        self,
        masses: tuple[float, ...],
        px: list[float],
        py: list[float],
        pz: list[float],
        vx: list[float],
        vy: list[float],
        vz: list[float],
        ax: list[float],
        ay: list[float],
        az: list[float],
        moving: bool,
    ) -> Shape:
        inv_m = 1.0 / self.total_mass
        cx = sum(m * x for m, x in zip(masses, px, strict=True)) * inv_m
        cy = sum(m * y for m, y in zip(masses, py, strict=True)) * inv_m
        cz = sum(m * z for m, z in zip(masses, pz, strict=True)) * inv_m
        rx = [x - cx for x in px]
        ry = [y - cy for y in py]
        rz = [z - cz for z in pz]
        sxx = syy = szz = sxy = sxz = syz = 0.0
        for m, x, y, z in zip(masses, rx, ry, rz, strict=True):
            sxx += m * x * x
            syy += m * y * y
            szz += m * z * z
            sxy += m * x * y
            sxz += m * x * z
            syz += m * y * z
        inertia = (syy + szz, sxx + szz, sxx + syy, -sxy, -sxz, -syz)
        shape = Shape()
        shape.rx, shape.ry, shape.rz = rx, ry, rz
        shape.com_geometric = (cx, cy, cz)
        shape.inertia = inertia
        shape.inertia_inv = sym_inverse(inertia)
        shape.radius_max = math.sqrt(
            max(x * x + y * y + z * z for x, y, z in zip(rx, ry, rz, strict=True))
        )
        shape.moving = moving
        if not moving:
            zeros = [0.0] * 10
            shape.vx = shape.vy = shape.vz = zeros
            shape.ax = shape.ay = shape.az = zeros
            shape.inertia_dot = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            shape.h = shape.h_dot = (0.0, 0.0, 0.0)
            shape.kinetic_energy_relative = shape.kinetic_energy_relative_dot = 0.0
            shape.speed_max = 0.0
            return shape
        dcx = sum(m * v for m, v in zip(masses, vx, strict=True)) * inv_m
        dcy = sum(m * v for m, v in zip(masses, vy, strict=True)) * inv_m
        dcz = sum(m * v for m, v in zip(masses, vz, strict=True)) * inv_m
        ddcx = sum(m * a for m, a in zip(masses, ax, strict=True)) * inv_m
        ddcy = sum(m * a for m, a in zip(masses, ay, strict=True)) * inv_m
        ddcz = sum(m * a for m, a in zip(masses, az, strict=True)) * inv_m
        vx = [v - dcx for v in vx]
        vy = [v - dcy for v in vy]
        vz = [v - dcz for v in vz]
        ax = [a - ddcx for a in ax]
        ay = [a - ddcy for a in ay]
        az = [a - ddcz for a in az]
        hx = hy = hz = hdx = hdy = hdz = 0.0
        # T = sum m r dr^T (for dI/dt), kinetic energy and its rate
        txx = tyy = tzz = txy = txz = tyz = 0.0
        ke = ke_dot = 0.0
        speed2 = 0.0
        for i in range(N_MASSES):
            m = masses[i]
            x, y, z = rx[i], ry[i], rz[i]
            u, v, w = vx[i], vy[i], vz[i]
            a, b, c = ax[i], ay[i], az[i]
            hx += m * (y * w - z * v)
            hy += m * (z * u - x * w)
            hz += m * (x * v - y * u)
            hdx += m * (y * c - z * b)
            hdy += m * (z * a - x * c)
            hdz += m * (x * b - y * a)
            txx += m * x * u
            tyy += m * y * v
            tzz += m * z * w
            txy += m * (x * v + y * u)
            txz += m * (x * w + z * u)
            tyz += m * (y * w + z * v)
            s2 = u * u + v * v + w * w
            ke += m * s2
            ke_dot += m * (u * a + v * b + w * c)
            speed2 = max(speed2, s2)
        # dI/dt = sum m (2 (r.dr) E - r dr^T - dr r^T)
        trace = txx + tyy + tzz
        shape.inertia_dot = (
            2.0 * (trace - txx),
            2.0 * (trace - tyy),
            2.0 * (trace - tzz),
            -txy,
            -txz,
            -tyz,
        )
        shape.vx, shape.vy, shape.vz = vx, vy, vz
        shape.ax, shape.ay, shape.az = ax, ay, az
        shape.h = (hx, hy, hz)
        shape.h_dot = (hdx, hdy, hdz)
        shape.kinetic_energy_relative = 0.5 * ke
        shape.kinetic_energy_relative_dot = ke_dot
        shape.speed_max = math.sqrt(speed2)
        return shape
