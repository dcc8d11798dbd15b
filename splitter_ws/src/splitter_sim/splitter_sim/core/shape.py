"""Shape of the morphing body: the ten lumped masses, their motion and the inertia tensor.

Given the 25 joint positions, velocities and accelerations, :func:`evaluate_shape`
returns, in the body frame ``base`` (origin at the centre of mass, x along the
tether), the positions ``r_i``, velocities ``dr_i`` and accelerations ``ddr_i``
of the ten masses relative to the centre of mass, and the quantities the
rotational dynamics needs: the inertia tensor about the centre of mass (products
included) and its inverse, the relative angular momentum ``h = sum m r x dr``,
its rate, ``dI/dt`` and the rate of the relative kinetic energy.

Positions are exactly those of :mod:`splitter_model.kinematics`
(``limb_offsets_from_joint_positions`` + ``lumped_mass_positions``, then taken
relative to ``center_of_mass``; the unit tests assert it); the derivatives are
the analytic time derivatives of the same forward kinematics. This is the hot
path of the simulator, hence plain floats and the ``math`` module: numpy on
3-vectors costs microseconds per call. The formulas (:func:`mass_motion`,
:func:`about_com_moving`, :func:`relative_motion`, :func:`sym_inverse_det`) take
the math functions as a namespace, so that the compiled kernels
(:mod:`.kernels`) build their graph by calling them with CasADi symbols.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import limb_frame
from splitter_model.model import RobotModel

N_MASSES = 10
BODY_INDICES = (0, 5)  # hemi a body, hemi b body
HEMI_OF_MASS = (0, 0, 0, 0, 0, 1, 1, 1, 1, 1)


class Shape:
    """Mass distribution of the body at one instant (body frame, relative to the COM).

    Plain-float containers (lists of length 10 per axis, 6-tuples for symmetric
    tensors ``(xx, yy, zz, xy, xz, yz)``) so that the integrator's stages stay cheap.
    """

    __slots__ = (
        "_geometric",
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
        "relative_ready",
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

    def relative(self) -> Shape:
        """Fill the per-mass lists (``rx`` ... ``az``) relative to the COM; returns self.

        A moving shape is built from mass-weighted sums only (all the integrator
        needs in flight); the per-mass lists, needed for contact, thrust and
        outputs, are made on first use.
        """
        if self.relative_ready:
            return self
        rel = relative_motion(*self._geometric)
        self.rx, self.ry, self.rz, self.vx, self.vy, self.vz, self.ax, self.ay, self.az = rel
        self.relative_ready = True
        return self

    def positions(self) -> NDArray[np.float64]:
        """Mass positions (10, 3) relative to the COM, body frame [m]."""
        self.relative()
        return np.column_stack([self.rx, self.ry, self.rz])

    def velocities(self) -> NDArray[np.float64]:
        """Mass velocities (10, 3) relative to the body, body frame [m/s]."""
        self.relative()
        return np.column_stack([self.vx, self.vy, self.vz])

    def accelerations(self) -> NDArray[np.float64]:
        """Mass accelerations (10, 3) relative to the body, body frame [m/s^2]."""
        self.relative()
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
    return sym_inverse_det(s, checked=True)[0]


def sym_inverse_det(s: Sequence[Any], checked: bool = False) -> tuple[tuple[Any, ...], Any]:
    """(inverse, determinant) of a symmetric 3x3 matrix of 6 entries (floats or symbols).

    ``checked``: ValueError unless the determinant is positive (floats only).
    """
    xx, yy, zz, xy, xz, yz = s
    c_xx = yy * zz - yz * yz
    c_xy = xz * yz - xy * zz
    c_xz = xy * yz - xz * yy
    det = xx * c_xx + xy * c_xy + xz * c_xz
    if checked and not det > 0.0:
        raise ValueError(f"inertia tensor is singular or not positive definite (det {det})")
    inv = 1.0 / det
    inverse = (
        c_xx * inv,
        (xx * zz - xz * xz) * inv,
        (xx * yy - xy * xy) * inv,
        c_xy * inv,
        c_xz * inv,
        (xy * xz - xx * yz) * inv,
    )
    return inverse, det


def limb_constants() -> tuple[tuple[int, int, float, float, float, float, float], ...]:
    """Per limb: (first joint index, mass index, s, u_y, u_z, w_y, w_z).

    ``s`` is the x component of ``v`` (+1 hemi a, -1 hemi b); the limb frames of
    :func:`~splitter_model.kinematics.limb_frame` must be axis aligned with ``v``
    along x (ValueError otherwise).
    """
    limbs = []
    for limb in range(8):
        u, v, w = limb_frame(limb)
        if abs(u[0]) > 0.0 or abs(w[0]) > 0.0 or abs(v[1]) + abs(v[2]) > 0.0:
            raise ValueError("limb frames must be axis aligned with v along x")
        limbs.append(
            (
                3 * limb,  # first joint index
                limb + 1 + limb // 4,  # mass index
                float(v[0]),  # s: +1 hemi a, -1 hemi b
                float(u[1]),  # y of u
                float(u[2]),  # z of u
                float(w[1]),  # y of w
                float(w[2]),  # z of w
            )
        )
    return tuple(limbs)


def hemi_body_inertia(moments_kg_m2: Sequence[float]) -> tuple[float, float, float]:
    """A hemi body's own principal moments [kg m^2], validated: three finite numbers >= 0
    that a rigid body can have (each at most the sum of the other two); ValueError
    naming ``hemi_inertia_kg_m2`` otherwise."""
    try:
        if isinstance(moments_kg_m2, str | bytes):
            raise TypeError
        values = tuple(float(v) for v in moments_kg_m2)
    except (TypeError, ValueError):
        raise ValueError(f"hemi_inertia_kg_m2: 3 numbers, got {moments_kg_m2!r}") from None
    if len(values) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in values):
        raise ValueError(f"hemi_inertia_kg_m2: 3 finite numbers >= 0, got {moments_kg_m2!r}")
    jx, jy, jz = values
    if jx > jy + jz or jy > jx + jz or jz > jx + jy:
        raise ValueError(
            f"hemi_inertia_kg_m2: no rigid body has these moments {values} (each must be "
            "at most the sum of the other two)"
        )
    return jx, jy, jz


# --- the formulas, written once for floats (FLOAT_MATH) and CasADi symbols (casadi) ----------
# ``ops``: a namespace of cos, sin, sqrt and fmax (the larger of two values), as casadi's.
FLOAT_MATH = SimpleNamespace(cos=math.cos, sin=math.sin, sqrt=math.sqrt, fmax=max)


def mass_motion(  # noqa: PLR0917  (the joint state, then the model's constants)
    ops: Any,
    q: Sequence[Any],
    qd: Sequence[Any] | None,
    qdd: Sequence[Any] | None,
    l1: Any,
    l2: Any,
    limbs: Sequence[tuple[int, int, float, float, float, float, float]],
) -> tuple[list[Any], ...]:
    """Positions (px, py, pz) of the ten masses in the tether-midpoint frame [m].

    With ``qd`` (and ``qdd``) also their velocities and accelerations (vx ... az):
    the analytic time derivatives of the same kinematics. ``limbs``:
    :func:`limb_constants`; ``l1``, ``l2`` thigh and shank [m].
    """
    cos, sin = ops.cos, ops.sin
    half_tether = 0.5 * q[TETHER_INDEX]
    px = [half_tether, 0.0, 0.0, 0.0, 0.0, -half_tether, 0.0, 0.0, 0.0, 0.0]
    py = [0.0] * 10
    pz = [0.0] * 10
    if qd is None or qdd is None:
        for k, i, sg, uy, uz, wy, wz in limbs:
            q1, q2 = q[k], q[k + 1]
            q23 = q2 + q[k + 2]
            p_u = l1 * cos(q2) + l2 * cos(q23)
            p_p = l1 * sin(q2) + l2 * sin(q23)
            p_w = p_p * sin(q1)
            px[i] = px[0 if sg > 0.0 else 5] + sg * p_p * cos(q1)
            py[i] = uy * p_u + wy * p_w
            pz[i] = uz * p_u + wz * p_w
        return px, py, pz
    vb, ab = 0.5 * qd[TETHER_INDEX], 0.5 * qdd[TETHER_INDEX]
    vx = [vb, 0.0, 0.0, 0.0, 0.0, -vb, 0.0, 0.0, 0.0, 0.0]
    vy = [0.0] * 10
    vz = [0.0] * 10
    ax = [ab, 0.0, 0.0, 0.0, 0.0, -ab, 0.0, 0.0, 0.0, 0.0]
    ay = [0.0] * 10
    az = [0.0] * 10
    for k, i, sg, uy, uz, wy, wz in limbs:
        q1, q2 = q[k], q[k + 1]
        q23 = q2 + q[k + 2]
        d1, d2 = qd[k], qd[k + 1]
        d23 = d2 + qd[k + 2]
        e1, e2 = qdd[k], qdd[k + 1]
        e23 = e2 + qdd[k + 2]
        c1, s1 = cos(q1), sin(q1)
        c2, s2 = cos(q2), sin(q2)
        c23, s23 = cos(q23), sin(q23)
        a2, b2 = l1 * c2, l1 * s2
        a23, b23 = l2 * c23, l2 * s23
        p_u = a2 + a23
        p_p = b2 + b23
        dp_u = -b2 * d2 - b23 * d23
        dp_p = a2 * d2 + a23 * d23
        ddp_u = -a2 * d2 * d2 - b2 * e2 - a23 * d23 * d23 - b23 * e23
        ddp_p = a2 * e2 - b2 * d2 * d2 + a23 * e23 - b23 * d23 * d23
        # components along v (x) and w of p, dp, ddp; u components are p_u, dp_u, ddp_u
        cw = p_p * d1
        v_v, v_w = dp_p * c1 - cw * s1, dp_p * s1 + cw * c1
        cv2 = ddp_p - cw * d1
        cw2 = 2.0 * dp_p * d1 + p_p * e1
        a_v, a_w = cv2 * c1 - cw2 * s1, cv2 * s1 + cw2 * c1
        p_w = p_p * s1
        body = 0 if sg > 0.0 else 5
        px[i] = px[body] + sg * p_p * c1
        py[i] = uy * p_u + wy * p_w
        pz[i] = uz * p_u + wz * p_w
        vx[i] = vx[body] + sg * v_v
        vy[i] = uy * dp_u + wy * v_w
        vz[i] = uz * dp_u + wz * v_w
        ax[i] = ax[body] + sg * a_v
        ay[i] = uy * ddp_u + wy * a_w
        az[i] = uz * ddp_u + wz * a_w
    return px, py, pz, vx, vy, vz, ax, ay, az


def about_com_moving(
    ops: Any,
    masses: Sequence[Any],
    total_mass: Any,
    geometric: Sequence[Sequence[Any]],
    own_inertia: Sequence[Any] = (0.0, 0.0, 0.0),
) -> tuple[Any, ...]:
    """Mass-weighted sums of a moving shape about the tether midpoint, shifted to the COM.

    ``geometric``: (px, py, pz, vx, vy, vz, ax, ay, az) of :func:`mass_motion`;
    ``own_inertia``: the principal moments the two hemi bodies have of their own (base
    axes, constant: each body turns with the base) [kg m^2], added to the tensor. Returns
    (c, dc, ddc) of the COM (3-tuples), the inertia tensor and its rate (6-tuples), the
    relative angular momentum h and its rate (3-tuples), the relative kinetic energy
    and its rate, and upper bounds of the mass distances and speeds relative to the
    COM (for the contact look-ahead).

    One pass of sums, then the parallel-axis forms: ``sum m r r' = sum m p p' - M c c'``,
    ``h = sum m p x dp - M c x dc``, ``1/2 sum m |dr|^2 = 1/2 sum m |dp|^2 - 1/2 M |dc|^2``
    and likewise for the rates; the COM stays within centimetres of the midpoint, so
    nothing cancels.
    """
    px, py, pz, vx, vy, vz, ax, ay, az = geometric
    fmax = ops.fmax
    compare = fmax is max
    smx = smy = smz = svx = svy = svz = sax = say = saz = 0.0
    sxx = syy = szz = sxy = sxz = syz = 0.0
    txx = tyy = tzz = txy = txz = tyz = 0.0
    hx = hy = hz = hdx = hdy = hdz = 0.0
    ke = ke_dot = radius2 = speed2 = 0.0
    for i in range(N_MASSES):
        m = masses[i]
        x, y, z = px[i], py[i], pz[i]
        u, v, w = vx[i], vy[i], vz[i]
        a, b, c = ax[i], ay[i], az[i]
        mx, my, mz = m * x, m * y, m * z
        smx += mx
        smy += my
        smz += mz
        svx += m * u
        svy += m * v
        svz += m * w
        sax += m * a
        say += m * b
        saz += m * c
        sxx += mx * x
        syy += my * y
        szz += mz * z
        sxy += mx * y
        sxz += mx * z
        syz += my * z
        txx += mx * u
        tyy += my * v
        tzz += mz * w
        txy += mx * v + my * u
        txz += mx * w + mz * u
        tyz += my * w + mz * v
        hx += my * w - mz * v
        hy += mz * u - mx * w
        hz += mx * v - my * u
        hdx += my * c - mz * b
        hdy += mz * a - mx * c
        hdz += mx * b - my * a
        s2 = u * u + v * v + w * w
        ke += m * s2
        ke_dot += m * (u * a + v * b + w * c)
        d2 = x * x + y * y + z * z
        if compare:  # floats: the comparison inline (a call of max costs ~80 ns)
            if d2 > radius2:  # noqa: PLR1730
                radius2 = d2
            if s2 > speed2:  # noqa: PLR1730
                speed2 = s2
        else:
            radius2 = fmax(radius2, d2)
            speed2 = fmax(speed2, s2)
    inv_m = 1.0 / total_mass
    cx, cy, cz = smx * inv_m, smy * inv_m, smz * inv_m
    dcx, dcy, dcz = svx * inv_m, svy * inv_m, svz * inv_m
    ddcx, ddcy, ddcz = sax * inv_m, say * inv_m, saz * inv_m
    sxx -= smx * cx
    syy -= smy * cy
    szz -= smz * cz
    sxy -= smx * cy
    sxz -= smx * cz
    syz -= smy * cz
    txx -= smx * dcx
    tyy -= smy * dcy
    tzz -= smz * dcz
    txy -= smx * dcy + smy * dcx
    txz -= smx * dcz + smz * dcx
    tyz -= smy * dcz + smz * dcy
    hx -= smy * dcz - smz * dcy
    hy -= smz * dcx - smx * dcz
    hz -= smx * dcy - smy * dcx
    hdx -= smy * ddcz - smz * ddcy
    hdy -= smz * ddcx - smx * ddcz
    hdz -= smx * ddcy - smy * ddcx
    ke -= svx * dcx + svy * dcy + svz * dcz
    ke_dot -= svx * ddcx + svy * ddcy + svz * ddcz
    trace = txx + tyy + tzz
    sqrt = ops.sqrt
    return (
        (cx, cy, cz),
        (dcx, dcy, dcz),
        (ddcx, ddcy, ddcz),
        (
            syy + szz + own_inertia[0],
            sxx + szz + own_inertia[1],
            sxx + syy + own_inertia[2],
            -sxy,
            -sxz,
            -syz,
        ),
        # dI/dt = sum m (2 (r.dr) E - r dr^T - dr r^T)
        (2.0 * (trace - txx), 2.0 * (trace - tyy), 2.0 * (trace - tzz), -txy, -txz, -tyz),
        (hx, hy, hz),
        (hdx, hdy, hdz),
        0.5 * ke,
        ke_dot,
        sqrt(radius2) + sqrt(cx * cx + cy * cy + cz * cz),
        sqrt(speed2) + sqrt(dcx * dcx + dcy * dcy + dcz * dcz),
    )


def relative_motion(
    geometric: Sequence[Sequence[Any]], com: Sequence[Sequence[Any]]
) -> tuple[list[Any], ...]:
    """rx ... az of the masses relative to the COM from ``geometric`` and (c, dc, ddc)."""
    px, py, pz, vx, vy, vz, ax, ay, az = geometric
    (cx, cy, cz), (dcx, dcy, dcz), (ddcx, ddcy, ddcz) = com
    return (
        [x - cx for x in px],
        [y - cy for y in py],
        [z - cz for z in pz],
        [v - dcx for v in vx],
        [v - dcy for v in vy],
        [v - dcz for v in vz],
        [a - ddcx for a in ax],
        [a - ddcy for a in ay],
        [a - ddcz for a in az],
    )


class ShapeKinematics:
    """Precomputed constants of the ten-mass forward kinematics of one model.

    The limb frames of :func:`~splitter_model.kinematics.limb_frame` are axis
    aligned: ``u`` is +-y or +-z, ``v = s x`` and ``w = u x v`` the remaining axis.
    A tip at ``p_u u + p_p (cos q1 v + sin q1 w)`` therefore has x component
    ``s p_p cos q1`` and y, z components from ``p_u`` and ``p_p sin q1``; the
    constants below pick them without multiplying by zeros.
    """

    def __init__(
        self, model: RobotModel, hemi_inertia_kg_m2: Sequence[float] = (0.0, 0.0, 0.0)
    ) -> None:
        """``hemi_inertia_kg_m2``: each hemi body's own principal moments about its
        centre, base axes [kg m^2] (the lumped-mass model's bodies are points: zero)."""
        self.model = model
        self.l1 = model.thigh_length_m  # [m]
        self.l2 = model.shank_length_m  # [m]
        self.masses = tuple(float(m) for m in model.lumped_masses_kg)  # [kg]
        self.total_mass = float(sum(self.masses))  # [kg]
        self.limbs = limb_constants()
        # both hemi bodies, rigidly turning with the base [kg m^2]
        self.own_inertia = tuple(2.0 * j for j in hemi_body_inertia(hemi_inertia_kg_m2))

    def evaluate(
        self,
        q: Sequence[float],
        qd: Sequence[float] | None = None,
        qdd: Sequence[float] | None = None,
    ) -> Shape:
        """Shape for joint positions ``q`` (25), velocities ``qd`` and accelerations ``qdd``.

        ``qd``/``qdd`` of None (or all zero) mean the joints are at rest.
        """
        moving = qd is not None and (any(qd) or (qdd is not None and any(qdd)))
        if qd is None or not moving:
            px, py, pz = mass_motion(FLOAT_MATH, q, None, None, self.l1, self.l2, self.limbs)
            return self._about_com(px, py, pz)
        if qdd is None:
            qdd = (0.0,) * 25
        return self._about_com_moving(
            mass_motion(FLOAT_MATH, q, qd, qdd, self.l1, self.l2, self.limbs)
        )

    def _about_com(self, px: list[float], py: list[float], pz: list[float]) -> Shape:
        """The shape at rest: positions about the COM, then the sums (exact for a resting shape)."""
        masses = self.masses
        inv_m = 1.0 / self.total_mass
        cx = cy = cz = 0.0
        for m, x, y, z in zip(masses, px, py, pz, strict=True):
            cx += m * x
            cy += m * y
            cz += m * z
        cx *= inv_m
        cy *= inv_m
        cz *= inv_m
        rx = [x - cx for x in px]
        ry = [y - cy for y in py]
        rz = [z - cz for z in pz]
        sxx = syy = szz = sxy = sxz = syz = 0.0
        radius2 = 0.0
        for m, x, y, z in zip(masses, rx, ry, rz, strict=True):
            mx, my = m * x, m * y
            sxx += mx * x
            syy += my * y
            szz += m * z * z
            sxy += mx * y
            sxz += mx * z
            syz += my * z
            d2 = x * x + y * y + z * z
            if d2 > radius2:  # noqa: PLR1730  (hot path: no call)
                radius2 = d2
        jx, jy, jz = self.own_inertia
        inertia = (syy + szz + jx, sxx + szz + jy, sxx + syy + jz, -sxy, -sxz, -syz)
        shape = Shape()
        shape.rx, shape.ry, shape.rz = rx, ry, rz
        shape.relative_ready = True
        shape.com_geometric = (cx, cy, cz)
        shape.inertia = inertia
        shape.inertia_inv = sym_inverse(inertia)
        shape.radius_max = math.sqrt(radius2)
        zeros = [0.0] * 10
        shape.moving = False
        shape.vx = shape.vy = shape.vz = zeros
        shape.ax = shape.ay = shape.az = zeros
        shape.inertia_dot = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        shape.h = shape.h_dot = (0.0, 0.0, 0.0)
        shape.kinetic_energy_relative = shape.kinetic_energy_relative_dot = 0.0
        shape.speed_max = 0.0
        return shape

    def _about_com_moving(self, geometric: tuple[list[float], ...]) -> Shape:
        """A moving shape from the masses' motion about the tether midpoint.

        The per-mass lists relative to the COM are made on first use (:meth:`Shape.relative`).
        """
        sums = about_com_moving(
            FLOAT_MATH, self.masses, self.total_mass, geometric, self.own_inertia
        )
        com, dcom, ddcom, inertia, inertia_dot, h, h_dot, ke, ke_dot, radius, speed = sums
        shape = Shape()
        shape._geometric = (geometric, (com, dcom, ddcom))
        shape.relative_ready = False
        shape.moving = True
        shape.com_geometric = com
        shape.inertia = inertia
        shape.inertia_inv = sym_inverse(inertia)
        shape.inertia_dot = inertia_dot
        shape.h = h
        shape.h_dot = h_dot
        shape.kinetic_energy_relative = ke
        shape.kinetic_energy_relative_dot = ke_dot
        shape.radius_max = radius
        shape.speed_max = speed
        return shape
