"""The reference MPC written the plain way: CasADi Opti + IPOPT, built once.

Same optimal control problem as :mod:`.ocp`, in the paper's own variables
(state ``[w, q, Ixx, Iyy, Izz]``, control ``dI``) and with the hardware limits
written as they read (linear constraints on the squared radii ``A I`` and their
steps ``A dI``), the way a first implementation would. Warm-started from the
shifted previous solution (primal only), like the project's controller, so that
``splitter bench mpc`` compares solvers on the same problem and the same
information. Used only by the benchmark and its test.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from splitter_model.model import RobotModel
from splitter_model.reachable import ReachableSet
from splitter_mpc.core.limits import axis_inertia_range, morphing_limits
from splitter_mpc.core.mpc import MpcPlan, MpcSettings, PlanRequest
from splitter_mpc.core.ocp import discrete_dynamics, momentum_target
from splitter_mpc.core.solvers import SolverResult


class OptiBaselineMpc:
    """Opti + IPOPT on the paper's variables; the interface of ``InertialMorphingMpc``."""

    def __init__(self, model: RobotModel, settings: MpcSettings | None = None) -> None:
        self.model = model
        self.settings = settings or MpcSettings(solver="ipopt")
        n, dt = self.settings.horizon, self.settings.dt_s
        self.limits = lim = morphing_limits(
            model, dt, self.settings.tension_min_n, self.settings.radius_rate_scale
        )
        a_sq = ca.DM(lim.radius_squared_matrix)
        opti = ca.Opti()
        w = opti.variable(3, n + 1)
        q = opti.variable(4, n + 1)
        inertia = opti.variable(3, n + 1)
        d_inertia = opti.variable(3, n)
        slack = opti.variable(1, n)
        self._p_x0 = opti.parameter(10)
        self._p_w_ref = opti.parameter(3)
        self._p_q_ref = opti.parameter(4, n + 1)
        self._p_q_w = opti.parameter(3)
        self._p_r = opti.parameter(3)
        self._p_q_t = opti.parameter(3)
        self._p_q_q = opti.parameter()
        self._p_q_tq = opti.parameter()
        self._p_slack = opti.parameter()
        self._p_rate = opti.parameter(3, n)  # [m^2] bound on A dI_k
        self._p_tension = opti.parameter(1, n)  # lower bound of w_y^2 + w_z^2
        self._p_paper = opti.parameter()  # 1: the paper's J_w, 0: the momentum objective
        self._p_axis = opti.parameter(3)  # reference axis e
        self._p_h_norm = opti.parameter()  # |H|
        self._p_spin = opti.parameter()  # reachable spin rate about e
        self._p_i_nom = opti.parameter(3)
        self._p_q_spin = opti.parameter(2)  # e' Q_w e, e' Q_t e
        m_inv = ca.DM(np.linalg.inv(lim.radius_squared_matrix))

        def rate_error(k: int):
            paper = w[:, k] - self._p_w_ref
            axis = self._p_axis
            momentum = (inertia[:, k] * w[:, k] - self._p_h_norm * axis) / self._p_i_nom
            perpendicular = w[:, k] - axis * ca.dot(axis, w[:, k])
            spin = perpendicular + axis * ca.dot(axis, momentum)
            return self._p_paper * paper + (1 - self._p_paper) * spin

        def spin_error(k: int):
            axis_inertia = ca.dot(self._p_axis**2, inertia[:, k]) + self._p_paper
            return self._p_h_norm / axis_inertia - self._p_spin

        opti.subject_to(w[:, 0] == self._p_x0[0:3])
        opti.subject_to(q[:, 0] == self._p_x0[3:7])
        opti.subject_to(inertia[:, 0] == self._p_x0[7:10])
        cost = 0
        for k in range(n):
            # dynamics with the correct gyroscopic sign (see ocp.py)
            opti.subject_to(inertia[:, k + 1] == inertia[:, k] + d_inertia[:, k])
            # the same model (correct gyroscopic sign, see ocp.py), written on I not s
            x_k = ca.vertcat(w[:, k], q[:, k], ca.mtimes(a_sq, inertia[:, k]))
            u_k = ca.vertcat(ca.mtimes(a_sq, d_inertia[:, k]), 0)
            x_next = discrete_dynamics(x_k, u_k, dt, m_inv, self.settings.integrator)
            opti.subject_to(w[:, k + 1] == x_next[0:3])
            opti.subject_to(q[:, k + 1] == x_next[3:7])
            # hardware limits
            opti.subject_to(
                opti.bounded(
                    -self._p_rate[:, k], ca.mtimes(a_sq, d_inertia[:, k]), self._p_rate[:, k]
                )
            )
            opti.subject_to(
                opti.bounded(
                    lim.radius_min_m**2, ca.mtimes(a_sq, inertia[:, k + 1]), lim.radius_max_m**2
                )
            )
            opti.subject_to(slack[k] >= 0)
            if k >= 1:
                opti.subject_to(w[1, k] ** 2 + w[2, k] ** 2 + slack[k] >= self._p_tension[k])
            e = rate_error(k)
            q_ref = self._p_q_ref[:, k]
            cost += ca.dot(e, self._p_q_w * e) + self._p_q_spin[0] * spin_error(k) ** 2
            cost += self._p_q_q * 0.5 * (1 - ca.dot(q_ref, q[:, k]) ** 2)
            cost += ca.dot(d_inertia[:, k], self._p_r * d_inertia[:, k])
            cost += self._p_slack * slack[k] + 1e-4 * slack[k] ** 2
        e = rate_error(n)
        cost += ca.dot(e, self._p_q_t * e) + self._p_q_spin[1] * spin_error(n) ** 2
        cost += self._p_q_tq * 0.5 * (1 - ca.dot(self._p_q_ref[:, n], q[:, n]) ** 2)
        opti.minimize(cost)
        opti.solver(
            "ipopt",
            {"print_time": False},
            {"print_level": 0, "sb": "yes", "tol": self.settings.options.tol},
        )
        x_sym = ca.SX.sym("x", 10)
        self._step_f = ca.Function(
            "F",
            [x_sym],
            [discrete_dynamics(x_sym, ca.SX.zeros(4), dt, m_inv, self.settings.integrator)],
        )
        self._opti = opti
        self._vars = (w, q, inertia, d_inertia, slack)
        self._last: tuple[int, dict] | None = None

    def _step(self, x: np.ndarray) -> np.ndarray:
        """One step of the MPC model at constant inertia."""
        return np.asarray(self._step_f(x), dtype=float).ravel()

    @property
    def horizon(self) -> int:
        return self.settings.horizon

    @property
    def reachable(self) -> ReachableSet:
        """The reachable set it plans within (the model's: the baseline knows no faults)."""
        return self.limits.reachable

    @property
    def radius_bounds_m(self) -> None:
        """No fault's radius bounds: the baseline plans the whole reachable set."""
        return None

    def set_radius_bounds(self, radius_min_m: object, radius_max_m: object) -> None:
        """Refused unless None (a benchmark of the nominal problem)."""
        if radius_min_m is not None or radius_max_m is not None:
            raise ValueError("the Opti baseline plans the nominal reachable set only")

    def reset(self) -> None:
        self._last = None

    def solve(self, request: PlanRequest) -> MpcPlan:
        """Same contract as :meth:`InertialMorphingMpc.solve` (no q_i term)."""
        t_ns, w_ref_rad_s = request.t_ns, request.w_ref_rad_s
        if any(request.weights.q_i):
            raise ValueError("the Opti baseline has no nominal-configuration term q_i")
        weights = request.weights.per_stage(self.settings.weights_step_ratio)
        opti, lim, n, dt = self._opti, self.limits, self.horizon, self.settings.dt_s
        x0 = np.asarray(request.state, dtype=float).reshape(10).copy()
        x0[3:7] /= np.linalg.norm(x0[3:7])
        s_now = np.clip(lim.radii_squared(x0[7:10]), lim.radius_min_m**2, lim.radius_max_m**2)
        x0[7:10] = np.linalg.solve(lim.radius_squared_matrix, s_now)
        r_now = np.sqrt(s_now)
        k = np.arange(n)[:, None]
        r_low = np.maximum(lim.radius_min_m, r_now - lim.radius_rate_max_m_s * k * dt)
        opti.set_value(self._p_x0, x0)
        opti.set_value(self._p_w_ref, np.asarray(w_ref_rad_s, dtype=float))
        q_ref = np.asarray(request.q_ref_wxyz, dtype=float).reshape(n + 1, 4)
        opti.set_value(self._p_q_ref, q_ref.T)
        opti.set_value(self._p_q_w, weights.q_w)
        opti.set_value(self._p_r, weights.r)
        opti.set_value(self._p_q_t, weights.q_t)
        opti.set_value(self._p_q_q, weights.q_q)
        opti.set_value(self._p_q_tq, weights.q_tq)
        opti.set_value(self._p_slack, weights.tension_slack)
        h_norm = float(np.linalg.norm(x0[7:10] * x0[0:3]))
        axis, _ = momentum_target(w_ref_rad_s, h_norm)
        axis, spin = momentum_target(w_ref_rad_s, h_norm, axis_inertia_range(lim, axis))
        scales = weights.residual_scales(axis)  # the same blend and spin weights as the OCP
        opti.set_value(self._p_paper, scales[15])
        opti.set_value(self._p_axis, axis)
        opti.set_value(self._p_h_norm, h_norm)
        opti.set_value(self._p_spin, spin)
        nominal = request.nominal_inertia_kg_m2
        opti.set_value(self._p_i_nom, x0[7:10] if nominal is None else nominal)
        opti.set_value(self._p_q_spin, 0.5 * scales[16:18] ** 2)
        r_next_low = np.maximum(lim.radius_min_m, r_now - lim.radius_rate_max_m_s * (k + 1) * dt)
        opti.set_value(self._p_rate, (2.0 * lim.radius_step_max_m * r_next_low).T)
        opti.set_value(self._p_tension, lim.tension_min_n / (lim.body_mass_kg * r_low[:, 0]))
        self._set_initial(int(t_ns), x0)
        w, q, inertia, d_inertia, slack = self._vars
        started = time.perf_counter()
        try:
            sol = opti.solve()
            ok, status = True, opti.stats()["return_status"]
            value = sol.value
        except RuntimeError:
            ok, status = False, opti.stats()["return_status"]
            value = opti.debug.value
        elapsed = time.perf_counter() - started
        values = {
            "w": np.asarray(value(w)),
            "q": np.asarray(value(q)),
            "inertia": np.asarray(value(inertia)),
            "d_inertia": np.asarray(value(d_inertia)).reshape(3, n),
            "slack": np.asarray(value(slack)).reshape(1, n),
        }
        if ok:
            self._last = (int(t_ns), values)
        result = SolverResult(
            z=np.zeros(0),
            lam_g=np.zeros(0),
            lam_z=np.zeros(0),
            status=str(status),
            converged=ok,
            usable=ok,
            iterations=int(opti.stats().get("iter_count", -1)),
            solve_time_s=elapsed,
            cost=float(value(opti.f)) if ok else float("nan"),
            infeasibility=0.0 if ok else float("inf"),
        )
        inertia_plan = values["inertia"].T
        return MpcPlan(
            t_ns=int(t_ns),
            dt_ns=self.settings.dt_ns,
            angular_velocity=values["w"].T,
            orientation=values["q"].T,
            inertia=inertia_plan,
            radii=np.sqrt(np.maximum(inertia_plan @ lim.radius_squared_matrix.T, 0.0)),
            result=result,
        )

    def _set_initial(self, t_ns: int, x0: np.ndarray) -> None:
        """Shifted previous solution (tail rolled out), or the initial state everywhere."""
        opti, n = self._opti, self.horizon
        w, q, inertia, d_inertia, slack = self._vars
        shift = None
        if self._last is not None:
            elapsed = t_ns - self._last[0]
            if elapsed >= 0 and elapsed % self.settings.dt_ns == 0:
                shift = elapsed // self.settings.dt_ns
        if shift is None or shift >= n:
            opti.set_initial(w, np.tile(x0[0:3, None], (1, n + 1)))
            opti.set_initial(q, np.tile(x0[3:7, None], (1, n + 1)))
            opti.set_initial(inertia, np.tile(x0[7:10, None], (1, n + 1)))
            opti.set_initial(d_inertia, np.zeros((3, n)))
            opti.set_initial(slack, np.zeros((1, n)))
            return
        last = self._last[1]
        kept = n + 1 - shift
        states = {key: last[key][:, shift:].copy() for key in ("w", "q", "inertia")}
        states["w"][:, 0], states["q"][:, 0], states["inertia"][:, 0] = x0[0:3], x0[3:7], x0[7:10]
        controls = np.hstack([last["d_inertia"][:, shift:], np.zeros((3, shift))])
        # the tail rolled out with zero control, as the project's controller does
        w_t, q_t, i_t = states["w"][:, -1], states["q"][:, -1], states["inertia"][:, -1]
        tail = {"w": [], "q": [], "inertia": []}
        for _ in range(n + 1 - kept):
            x_t = self._step(np.concatenate([w_t, q_t, self.limits.radii_squared(i_t)]))
            w_t, q_t = x_t[0:3], x_t[3:7]
            tail["w"].append(w_t)
            tail["q"].append(q_t)
            tail["inertia"].append(i_t)
        for key, value in states.items():
            if tail[key]:
                states[key] = np.hstack([value, np.array(tail[key]).T])
        opti.set_initial(w, states["w"])
        opti.set_initial(q, states["q"])
        opti.set_initial(inertia, states["inertia"])
        opti.set_initial(d_inertia, controls)
        opti.set_initial(slack, np.hstack([last["slack"][:, shift:], np.zeros((1, shift))]))
