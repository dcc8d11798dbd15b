"""A solve bounded by construction: condensed Gauss-Newton SQP with a line search.

The OCP of :mod:`.ocp` has a fixed initial state, so its states are a function
of its controls: ``x_{k+1} = F(x_k, u_k)`` rolled out from ``x_0``. This
back-end solves the same problem over the controls ``v = (u_0, ..., u_{N-1})``
alone (single shooting, "condensed"):

* **Derivatives.** One compiled function gives the rollout, the residuals
  ``r(v)`` and their Jacobian ``J_r = (dr/dz) (dz/dv)``, the constraint values
  (the states' radius bounds, the tether-tension rows) and their Jacobian. The
  sensitivity ``dz/dv`` is built stage by stage from the stage Jacobians
  ``A_k = dF/dx``, ``B_k = dF/du`` (``G_{k+1} = A_k G_k + B_k E_k``), in CasADi's
  MX, so the code stays small (~3 s to compile) where algorithmic
  differentiation through the whole rollout in SX gave ~1 M lines and minutes
  of gcc.
* **Step.** The Gauss-Newton QP ``min 1/2 dv' J_r'J_r dv + grad' dv`` under the
  linearised constraints is dense (``N * NU`` = 100 variables for the
  25-step formulation) and is solved by DAQP, a dual active-set solver for
  small dense QPs (the ``daqp`` wheel), warm-started from the previous
  iteration's multipliers (the first QP of a solve from the multipliers of the
  last plan, shifted by the MPC), with an iteration cap.
* **Globalisation.** A backtracking (Armijo) line search on the exact L1 merit
  ``f + mu |violation|_1``, ``mu`` above the largest QP multiplier. The
  project's ``sqp``/``rti`` take full steps and drift in the closed loop.
* **Bounded.** At most ``max_iter`` SQP iterations (:class:`~.solvers.SolverOptions`),
  each with at most :data:`MAX_BACKTRACKS` merit evaluations and one QP of at
  most :data:`QP_MAX_ITER` active-set iterations: nothing in it can run unbounded, so it runs in the
  controller's own process (``isolated: false``). A capped iterate is executed
  as a plan if it is feasible (the radius bounds are linear in ``v`` and a
  line-search step keeps them; the tension has a slack).

Single shooting returns a dynamically consistent plan at every iterate: the gaps
of the multiple-shooting form are zero by construction.
"""

from __future__ import annotations

import logging
import math
import time

import casadi as ca
import daqp
import numpy as np
import piqp
from numpy.typing import NDArray

from splitter_mpc.core.codegen import CompilationError, compiled_functions
from splitter_mpc.core.ocp import NU, MorphingOcp
from splitter_mpc.core.solvers import ProblemInstance, SolverOptions, SolverResult

_LOG = logging.getLogger(__name__)
NAME = "condensed_sqp"
_GN_REGULARISATION = 1e-8  # added to J_r'J_r (the slacks have no quadratic cost of their own)
_ARMIJO = 1e-4  # [-] sufficient decrease of the merit, as a share of its directional derivative
_MERIT_GROWTH = 1.5  # [-] mu is kept above this times the largest QP multiplier
_INFINITE_BOUND = 1e30  # DAQP's infinity
_DAQP_OPTIMAL = (1, 2)  # exit flags: optimal, optimal with a soft constraint
_PIQP_EPS_ABS = 1e-9  # [-] piqp's absolute tolerance (its default 1e-8)
_PIQP_EPS_REL = 1e-10  # [-] piqp's relative tolerance
_PIQP_MAX_ITER = 100  # [-] interior-point iterations (measured: 19-24 on the QPs DAQP cycled on)
_ACTIVE_SHARE = 1e-8  # [-] an interior point's multiplier below this share of the largest: 0
MAX_BACKTRACKS = 10  # [-] halvings of a step per iteration (smallest step 2^-9)
QP_MAX_ITER = 1000  # [-] active-set iterations per QP (measured: p99 ~140 cold, 1 warm)
# [-] DAQP's feasibility tolerance. Its default (1e-6) lets a step cross a radius bound
# by up to 1e-6, which the merit's penalty (mu ~ 300) then prices above the step's whole
# decrease near the optimum: the line search failed on the first iteration of ~1 % of
# the re-plans of a tumble campaign.
QP_PRIMAL_TOL = 1e-10


def condensed_functions(ocp: MorphingOcp) -> tuple[ca.Function, ca.Function]:
    """(data, merit) of the condensed problem, as MX functions of ``(v, x_0, p)``.

    ``data`` -> the residuals' Jacobian J_r, the gradient of the objective, the
    constraint values c (states x_1..x_N, tension rows 1..N-1) and dc/dv, all dense.
    ``merit`` -> objective, c and the multiple-shooting decision vector z(v).
    """
    n, nx = ocp.horizon, ocp.state.nx
    nv = n * NU
    dynamics = ocp.dynamics()
    x_sym, u_sym = ca.SX.sym("x", nx), ca.SX.sym("u", NU)
    x_next = dynamics(x_sym, u_sym)
    stage = ca.Function(
        "morphing_stage",
        [x_sym, u_sym],
        [x_next, ca.jacobian(x_next, x_sym), ca.jacobian(x_next, u_sym)],
    )
    state_rows = np.concatenate([_range(ocp.x_index(k)) for k in range(1, n + 1)])
    constraints = ca.vertcat(ocp.z[state_rows.tolist()], ocp.g[ocp.tension_rows.tolist()])
    objective = 0.5 * ca.sumsqr(ocp.residual) + ocp.linear_cost
    in_z = ca.Function(
        "morphing_condensed_z",
        [ocp.z, ocp.p],
        [
            ocp.residual,
            ca.jacobian(ocp.residual, ocp.z),
            ca.gradient(ocp.linear_cost, ocp.z),
            constraints,
            ca.jacobian(constraints, ocp.z),
            objective,
        ],
    )
    v = ca.MX.sym("v", nv)
    x0 = ca.MX.sym("x0", nx)
    p = ca.MX.sym("p", ocp.p.numel())
    controls = ca.vertsplit(v, NU)
    states = [x0]
    sensitivity = ca.MX(nx, nv)  # G_k = dx_k/dv, structurally block lower triangular
    rows = [sensitivity]  # dz/dv, stage by stage
    for k in range(n):
        select = ca.DM(
            ca.Sparsity.triplet(NU, nv, list(range(NU)), list(range(k * NU, (k + 1) * NU))),
            1.0,
        )
        x_next, a_k, b_k = stage(states[-1], controls[k])
        sensitivity = ca.mtimes(a_k, sensitivity) + ca.mtimes(b_k, select)
        rows += [select, sensitivity]
        states.append(x_next)
    dz_dv = ca.vertcat(*rows)
    z_parts: list[ca.MX] = []
    for k in range(n):
        z_parts += [states[k], controls[k]]
    z = ca.vertcat(*z_parts, states[n])
    r, jac_r_z, linear_gradient_z, c, jac_c_z, f = in_z(z, p)
    jac_r = ca.mtimes(jac_r_z, dz_dv)
    gradient = ca.mtimes(jac_r.T, r) + ca.mtimes(dz_dv.T, linear_gradient_z)
    data = ca.Function(
        "morphing_condensed_data",
        [v, x0, p],
        [ca.densify(e) for e in (jac_r, gradient, c, ca.mtimes(jac_c_z, dz_dv))],
        ["v", "x0", "p"],
        ["jac_r", "grad", "c", "jac_c"],
    )
    merit = ca.Function(
        "morphing_condensed_merit",
        [v, x0, p],
        [ca.densify(e) for e in (f, c, z)],
        ["v", "x0", "p"],
        ["f", "c", "z"],
    )
    return data, merit


def _range(part: slice) -> NDArray[np.intp]:
    return np.arange(part.start, part.stop, dtype=np.intp)


class BufferedFunction:
    """A CasADi function called on numpy arrays without conversions (its ``buffer()`` API).

    Converting a 279 x 100 DM to numpy costs ~0.3 ms; here the function writes
    straight into arrays allocated once. Outputs are dense, matrices in
    column-major order; they are overwritten by the next call (copy to keep).
    """

    def __init__(self, function: ca.Function) -> None:
        self._buffer, self._evaluate = function.buffer()
        self._inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        self.outputs: list[NDArray[np.float64]] = []
        for i in range(function.n_out()):
            if function.nnz_out(i) != function.numel_out(i):
                raise ValueError(f"{function.name()}: output {i} must be dense")
            rows, cols = function.size_out(i)
            out = np.zeros((rows, cols), order="F") if cols > 1 else np.zeros(rows)
            self._buffer.set_res(i, memoryview(out.reshape(-1, order="F")))
            self.outputs.append(out)
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))

    def __call__(self, *args: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        for array, value in zip(self._inputs, args, strict=True):
            array[:] = value
        self._evaluate()
        return self.outputs


class CondensedSqpBackend:
    """The condensed SQP of the module docstring; a :mod:`.solvers` back-end."""

    name = NAME

    def __init__(self, ocp: MorphingOcp, options: SolverOptions) -> None:
        self.ocp = ocp
        self.options = options
        functions = list(condensed_functions(ocp))
        if options.compile:
            try:
                functions = compiled_functions(
                    "morphing_condensed_sqp", functions, options.cache_dir
                )
            except (CompilationError, RuntimeError) as exc:
                _LOG.warning("%s: compiled code unavailable (%s); using the MX VM", NAME, exc)
        self._data, self._merit = (BufferedFunction(f) for f in functions)
        n = ocp.horizon
        self._u_rows = np.concatenate([_range(ocp.u_index(k)) for k in range(n)])
        self._x_rows = np.concatenate([_range(ocp.x_index(k)) for k in range(1, n + 1)])
        self._x0_rows = _range(ocp.x_index(0))
        self.fallback_solves = 0  # QPs DAQP could not solve, handed to piqp

    def _bounds(self, data: ProblemInstance) -> tuple[NDArray, ...]:
        """(lbv, ubv, lbc, ubc, bounded): the controls' bounds and the bounded constraints'."""
        lbv, ubv = data.lbz[self._u_rows], data.ubz[self._u_rows]
        rows = self.ocp.tension_rows
        lbc = np.concatenate([data.lbz[self._x_rows], data.lbg[rows]])
        ubc = np.concatenate([data.ubz[self._x_rows], data.ubg[rows]])
        bounded = np.isfinite(lbc) | np.isfinite(ubc)
        return lbv, ubv, lbc[bounded], ubc[bounded], bounded

    def _duals_in(self, data: ProblemInstance, bounded: NDArray) -> NDArray | None:
        """DAQP's dual start from the NLP multipliers the MPC shifted (None: all zero)."""
        lam_c = np.concatenate([data.lam_z0[self._x_rows], data.lam_g0[self.ocp.tension_rows]])
        duals = np.concatenate([data.lam_z0[self._u_rows], lam_c[bounded]])
        return duals if np.any(duals) and np.all(np.isfinite(duals)) else None

    def _duals_out(
        self, duals: NDArray | None, bounded: NDArray
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lam_g, lam_z) of the NLP from the last QP's multipliers (zero without one)."""
        lam_g, lam_z = np.zeros(self.ocp.n_g), np.zeros(self.ocp.n_z)
        if duals is None:
            return lam_g, lam_z
        nv = self._u_rows.size
        lam_z[self._u_rows] = duals[:nv]
        lam_c = np.zeros(bounded.size)
        lam_c[bounded] = duals[nv:]
        lam_z[self._x_rows] = lam_c[: self._x_rows.size]
        lam_g[self.ocp.tension_rows] = lam_c[self._x_rows.size :]
        return lam_g, lam_z

    def feasible_start(self, data: ProblemInstance) -> NDArray[np.float64]:
        """The warm start's controls, made to keep every radius within its bounds.

        ``s_{k+1} = s_k + ds_k`` exactly, so each ``ds_k`` is clipped to its rate bound
        and to what keeps ``s_{k+1}`` within the state bounds (both contain 0 while
        ``s_k`` is within its own): from a measured state the shifted plan can leave
        them, and an iterate that starts outside may start where the rollout is not
        finite. Every later iterate keeps these linear bounds (the QP's step does, and
        so does any share of it).
        """
        n, nx = self.ocp.horizon, self.ocp.state.nx
        radii = self.ocp.state.radii_sq
        rate_lo = data.lbz[self._u_rows].reshape(n, NU)[:, 0:3]
        rate_hi = data.ubz[self._u_rows].reshape(n, NU)[:, 0:3]
        controls = np.clip(data.z0[self._u_rows], data.lbz[self._u_rows], data.ubz[self._u_rows])
        controls = controls.reshape(n, NU)
        state_lo = data.lbz[self._x_rows].reshape(n, nx)[:, radii]
        state_hi = data.ubz[self._x_rows].reshape(n, nx)[:, radii]
        s = data.lbz[self._x0_rows][radii]
        for k in range(n):
            # outside its bounds (never, from the MPC's projection) a radius heads back
            # at its top rate
            low = np.maximum(rate_lo[k], np.minimum(state_lo[k] - s, rate_hi[k]))
            high = np.minimum(rate_hi[k], np.maximum(state_hi[k] - s, rate_lo[k]))
            controls[k, 0:3] = np.clip(controls[k, 0:3], low, high)
            s = s + controls[k, 0:3]
        return controls.ravel()

    def _qp_step(
        self, qp: tuple[NDArray, ...], duals: NDArray | None
    ) -> tuple[NDArray, NDArray, str]:
        """(step, multipliers, "" or why it failed) of the QP ``(H, g, A, upper, lower)``.

        DAQP first, warm. Where its active set cycles (exit flag -2, or 4) the QP sits
        on a degenerate vertex: a tension row and its slack's bound active together and
        nearly parallel along a slow lunar spin, measured; piqp's interior point, which
        has no active set to cycle on, then solves it (:func:`interior_point_qp`;
        ~2 ms at 100 variables, ~9 ms at 200).
        """
        step, _, flag, info = daqp.solve(
            *qp, dual_start=duals, iter_limit=QP_MAX_ITER, primal_tol=QP_PRIMAL_TOL
        )
        lam = np.asarray(info["lam"], dtype=float)
        if flag in _DAQP_OPTIMAL and np.all(np.isfinite(step)) and np.all(np.isfinite(lam)):
            return np.asarray(step, dtype=float), lam, ""
        self.fallback_solves += 1
        step, lam, solved = interior_point_qp(*qp)
        if not solved:
            return step, lam, f"daqp {flag}, piqp unsolved"
        return step, lam, ""

    def solve(self, data: ProblemInstance) -> SolverResult:
        started = time.perf_counter()
        opts = self.options
        x0 = data.lbz[self._x0_rows]
        lbv, ubv, lbc, ubc, bounded = self._bounds(data)
        v = self.feasible_start(data)

        def violation(c: NDArray) -> float:
            return float(np.sum(np.maximum(lbc - c, 0.0) + np.maximum(c - ubc, 0.0)))

        def merit(v_try: NDArray) -> tuple[float, float]:
            f, c, _ = self._merit(v_try, x0, data.p)
            return float(f[0]), violation(c[bounded])

        regularisation = _GN_REGULARISATION * np.eye(v.size)
        duals = self._duals_in(data, bounded)
        status, converged, iterations, steps = "max_iter", False, 0, 0
        penalty = 1.0  # mu of the merit: above every multiplier of this solve's QPs
        f_now, viol_now = merit(v)
        start_finite = math.isfinite(f_now + viol_now)
        if not start_finite:
            status = "non_finite_start"
        cap = opts.max_iter if start_finite else 0
        for iterations in range(1, cap + 1):  # noqa: B007 (used after the loop)
            jac_r, grad, c, jac_c = self._data(v, x0, data.p)
            c = c[bounded]
            qp = (
                jac_r.T @ jac_r + regularisation,
                grad,
                jac_c[bounded],
                np.minimum(np.concatenate([ubv - v, ubc - c]), _INFINITE_BOUND),
                np.maximum(np.concatenate([lbv - v, lbc - c]), -_INFINITE_BOUND),
            )
            step, lam, failure = self._qp_step(qp, duals)
            if failure:
                status = f"qp_failed({failure})"
                break
            duals = lam
            penalty = max(penalty, _MERIT_GROWTH * float(np.max(np.abs(duals), initial=0.0)))
            phi = f_now + penalty * viol_now
            slope = float(grad @ step) - penalty * viol_now  # the merit's along the step
            alpha = 1.0
            for _ in range(MAX_BACKTRACKS):
                f_try, viol_try = merit(v + alpha * step)
                if f_try + penalty * viol_try <= phi + _ARMIJO * alpha * slope:
                    break
                alpha *= 0.5
            else:
                status = "line_search_failed"
                break
            v = v + alpha * step
            f_now, viol_now = f_try, viol_try
            steps += 1
            if np.max(np.abs(alpha * step) / (1.0 + np.abs(v))) <= opts.tol:
                status, converged = "converged", True
                break
            if time.perf_counter() - started > opts.max_time_s:
                status = "time_limit"
                break
        f, c, z = self._merit(v, x0, data.p)
        z = z.copy()
        cost = float(f[0])
        infeasibility = max(violation_max(c[bounded], lbc, ubc), violation_max(v, lbv, ubv))
        finite = bool(np.all(np.isfinite(z))) and math.isfinite(cost)
        if not finite:
            status, converged = "non_finite", False
        lam_g, lam_z = self._duals_out(duals, bounded)
        return SolverResult(
            z=z,
            lam_g=lam_g,
            lam_z=lam_z,
            status=status,
            converged=converged,
            # a failure before any step leaves the warm start: not a plan of this solve
            usable=finite and infeasibility <= opts.usable_infeasibility and steps > 0,
            iterations=iterations,
            solve_time_s=time.perf_counter() - started,
            cost=cost,
            infeasibility=infeasibility,
        )


def interior_point_qp(
    hessian: NDArray,
    gradient: NDArray,
    rows: NDArray,
    upper: NDArray,
    lower: NDArray,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """(x, multipliers, solved) of DAQP's QP form by piqp's dense interior point.

    ``upper``/``lower`` hold the simple bounds first, then the rows' (as DAQP takes
    them; +-1e30 is no bound). The multipliers come back in DAQP's convention
    (> 0 at an upper bound, < 0 at a lower one), those of inactive constraints (an
    interior point's are small, not zero) set to zero, so that they can warm-start DAQP.
    """
    n = gradient.size

    def unbounded(values: NDArray) -> NDArray:
        values = np.where(values >= _INFINITE_BOUND, np.inf, values)
        return np.where(values <= -_INFINITE_BOUND, -np.inf, values)

    solver = piqp.DenseSolver()
    solver.settings.eps_abs = _PIQP_EPS_ABS
    solver.settings.eps_rel = _PIQP_EPS_REL
    solver.settings.max_iter = _PIQP_MAX_ITER
    solver.setup(
        hessian,
        gradient,
        None,
        None,
        rows,
        unbounded(lower[n:]),
        unbounded(upper[n:]),
        unbounded(lower[:n]),
        unbounded(upper[:n]),
    )
    status = solver.solve()
    result = solver.result
    x = np.asarray(result.x, dtype=float)
    lam = np.concatenate(
        [
            np.asarray(result.z_bu, dtype=float) - np.asarray(result.z_bl, dtype=float),
            np.asarray(result.z_u, dtype=float) - np.asarray(result.z_l, dtype=float),
        ]
    )
    largest = float(np.max(np.abs(lam), initial=0.0))
    lam[np.abs(lam) <= _ACTIVE_SHARE * largest] = 0.0
    solved = status == piqp.PIQP_SOLVED and bool(
        np.all(np.isfinite(x)) and np.all(np.isfinite(lam))
    )
    return x, lam, solved


def violation_max(values: NDArray, lower: NDArray, upper: NDArray) -> float:
    """The largest violation of ``lower <= values <= upper`` (0 when none)."""
    return max(
        float(np.max(lower - values, initial=0.0)), float(np.max(values - upper, initial=0.0))
    )
