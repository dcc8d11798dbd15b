"""Numerical back-ends for :class:`~splitter_mpc.core.ocp.MorphingOcp`, chosen by name.

* ``fatrop`` (default): structure-exploiting interior point that ships with the
  casadi wheel; gaps written ``x_{k+1} - F``, stage structure given explicitly.
  With the hardware limits as simple bounds (:mod:`.ocp`) it converges in ~20
  iterations on the paper's closed loop and matches IPOPT to 1e-6.
* ``ipopt``: interior point, the reference; same problem.
* ``sqp``: sequential quadratic programming on the stage-structured QP solver
  hpipm with a generalised Gauss-Newton Hessian (``J_r' J_r`` of the least-squares
  residuals: the QP is convex, which hpipm's interior point needs; the exact
  Lagrangian Hessian of this problem is indefinite, eigenvalues down to -850,
  and hpipm then stalls at its iteration cap). Gauss-Newton ignores the
  constraint curvature, so on this large-residual problem it converges only
  linearly: kept for comparison (``splitter bench mpc``), not the default.
* ``rti``: the real-time iteration, ``sqp`` capped at one iteration per re-plan.
* ``condensed_sqp``: Gauss-Newton SQP over the controls alone, a dense QP per
  iteration (DAQP), a line search on an exact-penalty merit and an iteration
  cap: bounded by construction, so it needs no worker process
  (:mod:`.condensed_sqp`).

For ``ipopt`` and ``fatrop`` the objective is scaled as IPOPT's gradient-based
scaling does (``nlp_scaling_max_gradient``, ``nlp_scaling_min_value``): by
``min(1, max(1e-8, g_max / |grad f(z_0)|_inf))`` at the warm start, a parameter of
the compiled problem, so the tolerances
mean the same whatever the weights. fatrop has no scaling of its own; with
Table I's weights the gradient is ~500 and unscaled solves of the first,
hardest re-plans took up to 62 iterations, scaled ones ~35 (``splitter bench mpc``).
The problem is expanded to SX and its derivative
functions are compiled to C once and cached on disk (:mod:`.codegen`); ``sqp``
compiles its QP-data function the same way. Every back-end returns a
:class:`SolverResult`; ``usable`` says whether its plan may be executed
(converged, or for sqp/rti a feasible iterate).
"""

from __future__ import annotations

import logging
import math
import os
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from splitter_mpc.core.codegen import CompilationError, compiled_functions, compiled_library
from splitter_mpc.core.ocp import MorphingOcp
from splitter_msgs_py.core.parameter_fields import parameter_field

_LOG = logging.getLogger(__name__)
SOLVERS = ("fatrop", "ipopt", "sqp", "rti", "condensed_sqp")
# back-ends whose every loop is capped (iterations, line search, QP) and whose code
# has no native solver that can freeze: they need no worker process to be bounded
BOUNDED_SOLVERS = ("condensed_sqp",)
_GN_REGULARISATION = 1e-8  # added to the Gauss-Newton Hessian (states without a cost)
OBJECTIVE_GRADIENT_MAX = 100.0  # IPOPT's nlp_scaling_max_gradient
OBJECTIVE_SCALE_MIN = 1e-8  # IPOPT's nlp_scaling_min_value: a wild start is not scaled to 0


# [s] wall-time deadline of a solve in lockstep and library runs: there the simulator
# waits for the controller, so a slow solve is waited for and results never depend on
# load; the hardest solves take ~0.05 s (``splitter bench mpc``), a frozen one never ends.
LOCKSTEP_MAX_TIME_S = 2.0


class Closable(ABC):
    """Something holding a process to stop: call :meth:`close`, or use it in ``with``."""

    @abstractmethod
    def close(self) -> None:
        """Stop what it holds (idempotent)."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def close_part(part: object) -> None:
    """``part.close()`` if ``part`` has one (a back-end without a worker has none)."""
    close = getattr(part, "close", None)
    if close is not None:
        close()


@dataclass(frozen=True)
class SolverOptions:
    """Caps and tolerances shared by the back-ends.

    The fields made with ``parameter_field`` are ``inertial_morphing_mpc`` node
    parameters (:data:`splitter_mpc.core.mpc_tick.PARAMETER_NAMES` gives the node's
    name where it differs).
    """

    max_iter: int = parameter_field(30, "iteration cap per solve", bounds=(1, 10000))
    max_time_s: float = parameter_field(  # [s] real time: a late plan is dropped
        0.08,
        "wall-time deadline per solve [s]; a missed one executes the previous plan",
        bounds=(1e-3, 60.0),
    )
    # Run the back-end in a worker process that is killed at max_time_s
    # (:mod:`.solver_worker`): the only bound that holds when a native solve freezes.
    isolated: bool = parameter_field(
        True,
        "solve in a worker process killed at the deadline (the only bound that holds when "
        "a native solve freezes); false solves in the node's process",
    )
    # lockstep: a restarted worker's build is waited for outside the deadline
    # (deterministic); real time: it counts against it
    wait_for_worker_start: bool = parameter_field(
        True,
        "after a missed deadline, wait for the restarted worker outside the deadline "
        "(lockstep, deterministic); false counts its start against the deadline (real time)",
    )
    # optimality of the scaled problem (interior point) / step size (SQP)
    tol: float = parameter_field(1e-6, "solver tolerance (scaled problem)", bounds=(1e-14, 1e-2))
    # fatrop's own defaults in the casadi wheel (checked: setting them leaves every
    # iterate as it was; fatrop's sources at another version say mu_init 1e2)
    fatrop_mu_init: float = parameter_field(
        0.1, "fatrop: initial barrier parameter mu_init", bounds=(1e-12, 1e6)
    )
    fatrop_bound_push: float = parameter_field(
        1e-2,
        "fatrop: bound_push, how far the start is pushed inside its bounds",
        bounds=(1e-12, 0.5),
    )
    usable_infeasibility: float = 1e-4  # largest constraint violation of an executable plan
    # sqp/rti iterates carry the linearisation error of the dynamics (RTI's premise):
    rti_usable_infeasibility: float = 1e-2
    compile: bool = parameter_field(True, "compile the derivative code with gcc (cached on disk)")
    # a folder; "" or None: $SPLITTER_CACHE_DIR or ~/.cache/splitter (read as None)
    cache_dir: Path | str | None = parameter_field(  # noqa: RUF009 (a str default)
        "", "compiled-code cache ('' = $SPLITTER_CACHE_DIR or ~/.cache/splitter)"
    )

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be an int >= 1, got {self.max_iter!r}")
        for name in (
            "max_time_s",
            "tol",
            "usable_infeasibility",
            "rti_usable_infeasibility",
            "fatrop_mu_init",
            "fatrop_bound_push",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if isinstance(self.cache_dir, str):
            folder = Path(self.cache_dir).expanduser() if self.cache_dir else None
            object.__setattr__(self, "cache_dir", folder)


@dataclass(frozen=True)
class ProblemInstance:
    """Numbers of one solve: warm start, parameters and bounds."""

    z0: NDArray[np.float64]
    lam_g0: NDArray[np.float64]
    lam_z0: NDArray[np.float64]
    p: NDArray[np.float64]
    lbz: NDArray[np.float64]
    ubz: NDArray[np.float64]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]


@dataclass(frozen=True)
class SolverResult:
    """One solve: the primal-dual point and how it went."""

    z: NDArray[np.float64]
    lam_g: NDArray[np.float64]
    lam_z: NDArray[np.float64]
    status: str
    converged: bool
    usable: bool
    iterations: int
    solve_time_s: float  # [s] wall
    cost: float
    infeasibility: float  # largest violation of a constraint or bound


class _Evaluator:
    """Objective and constraint values, and the violation measure."""

    def __init__(self, fg: ca.Function) -> None:
        self._fg = fg

    def __call__(self, z: NDArray, data: ProblemInstance) -> tuple[float, float]:
        f, g = self._fg(z, data.p)
        g = np.asarray(g, dtype=float).ravel()
        violation = max(
            float(np.max(data.lbg - g, initial=0.0)),
            float(np.max(g - data.ubg, initial=0.0)),
            float(np.max(data.lbz - z, initial=0.0)),
            float(np.max(z - data.ubz, initial=0.0)),
        )
        cost = float(f)
        if not math.isfinite(cost) or not np.all(np.isfinite(g)):
            return math.nan, math.inf
        return cost, violation


def _fg_function(ocp: MorphingOcp) -> ca.Function:
    return ca.Function(
        "morphing_fg", [ocp.z, ocp.p], [ocp.objective, ocp.g], ["z", "p"], ["f", "g"]
    )


def fatrop_structure(ocp: MorphingOcp) -> dict:
    """fatrop's options that describe the OCP's stages (its manual structure detection)."""
    return {
        "structure_detection": "manual",
        "nx": ocp.nx,
        "nu": ocp.nu,
        "ng": ocp.ng,
        "N": ocp.horizon,
        "equality": ocp.equality,
    }


class NlpBackend:
    """IPOPT or fatrop through ``nlpsol`` (compiled derivative code when possible)."""

    def __init__(self, ocp: MorphingOcp, plugin: str, options: SolverOptions) -> None:
        if plugin not in ("ipopt", "fatrop"):
            raise ValueError(f"unknown nlpsol plugin {plugin!r}")
        self.name = plugin
        self.ocp = ocp
        self.options = options
        scale = ca.SX.sym("objective_scale")
        nlp = {
            "x": ocp.z,
            "p": ca.vertcat(ocp.p, scale),
            "f": scale * ocp.objective,
            "g": ocp.g,
        }
        common = {"print_time": False, "error_on_fail": False}
        if plugin == "ipopt":
            opts = {
                **common,
                "ipopt.print_level": 0,
                "ipopt.sb": "yes",
                "ipopt.max_iter": options.max_iter * 5,
                "ipopt.max_wall_time": options.max_time_s,
                "ipopt.tol": options.tol,
            }
        else:
            opts = {
                **common,
                **fatrop_structure(ocp),
                "fatrop.print_level": 0,
                "fatrop.max_iter": options.max_iter * 5,
                "fatrop.tol": options.tol,
                "fatrop.mu_init": options.fatrop_mu_init,
                "fatrop.bound_push": options.fatrop_bound_push,
            }
        expanded = ca.nlpsol(f"morphing_{plugin}", plugin, nlp, {**opts, "expand": True})
        self._solver = expanded
        if options.compile:
            try:
                library = compiled_library(
                    f"morphing_{plugin}_nlp",
                    lambda path: _generate_dependencies(expanded, path),
                    options.cache_dir,
                )
                self._solver = ca.nlpsol(f"morphing_{plugin}_c", plugin, str(library), opts)
            except (CompilationError, RuntimeError) as exc:
                _LOG.warning("%s: compiled code unavailable (%s); using the SX VM", plugin, exc)
        # the checks around each solve (scale at the warm start, cost and violation of
        # the answer) cost ~0.5 ms in the SX virtual machine, ~0.05 ms compiled
        checks = [
            _fg_function(ocp).expand(),
            ca.Function(
                "morphing_grad_f", [ocp.z, ocp.p], [ca.gradient(ocp.objective, ocp.z)]
            ).expand(),
        ]
        if options.compile:
            try:
                checks = compiled_functions("morphing_nlp_checks", checks, options.cache_dir)
            except (CompilationError, RuntimeError) as exc:
                _LOG.warning("%s: compiled checks unavailable (%s); using the SX VM", plugin, exc)
        self._evaluate = _Evaluator(checks[0])
        self._gradient = checks[1]

    def objective_scale(self, data: ProblemInstance) -> float:
        """IPOPT's gradient-based objective scale at the warm start (module docstring)."""
        gradient = np.asarray(self._gradient(data.z0, data.p), dtype=float)
        largest = float(np.max(np.abs(gradient), initial=0.0))
        if not math.isfinite(largest):
            return 1.0  # the solver reports the non-finite start itself
        if largest <= OBJECTIVE_GRADIENT_MAX:
            return 1.0
        return max(OBJECTIVE_SCALE_MIN, OBJECTIVE_GRADIENT_MAX / largest)

    def solve(self, data: ProblemInstance) -> SolverResult:
        started = time.perf_counter()
        scale = self.objective_scale(data)
        out = self._solver(
            x0=data.z0,
            lam_g0=data.lam_g0 * scale,
            lam_x0=data.lam_z0 * scale,
            p=np.append(data.p, scale),
            lbx=data.lbz,
            ubx=data.ubz,
            lbg=data.lbg,
            ubg=data.ubg,
        )
        elapsed = time.perf_counter() - started
        stats = self._solver.stats()
        z = np.asarray(out["x"], dtype=float).ravel()
        cost, violation = self._evaluate(z, data)
        converged = bool(stats.get("success", False))
        status = str(stats.get("return_status", "unknown"))
        finite = bool(np.all(np.isfinite(z)))
        return SolverResult(
            z=z,
            lam_g=np.asarray(out["lam_g"], dtype=float).ravel() / scale,
            lam_z=np.asarray(out["lam_x"], dtype=float).ravel() / scale,
            status=status,
            converged=converged and finite,
            usable=finite and converged and violation <= self.options.usable_infeasibility,
            iterations=int(stats.get("iter_count", -1)),
            solve_time_s=elapsed,
            cost=cost,
            infeasibility=violation,
        )


def _generate_dependencies(solver: ca.Function, path: Path) -> None:
    """C code of the NLP's derivative functions, written to ``path``.

    ``generate_dependencies`` only accepts a bare file name and writes into the
    working directory, so it runs from ``path``'s (private, temporary) folder.
    """
    cwd = Path.cwd()
    os.chdir(path.parent)
    try:
        solver.generate_dependencies(path.name)
    finally:
        os.chdir(cwd)


class SqpBackend:
    """Gauss-Newton SQP on hpipm, full steps, warm-started (module docstring)."""

    def __init__(
        self, ocp: MorphingOcp, options: SolverOptions, max_iter: int | None = None
    ) -> None:
        if ocp.gap_next_minus_f:
            raise ValueError("the sqp back-end needs gaps written F(x, u) - x_next (hpipm)")
        self.name = "sqp" if max_iter is None else "rti"
        self.ocp = ocp
        self.options = options
        self.max_iter = options.max_iter if max_iter is None else max_iter
        jac_r = ca.jacobian(ocp.residual, ocp.z)
        hessian = ca.mtimes(jac_r.T, jac_r) + _GN_REGULARISATION * ca.SX.eye(ocp.n_z)
        jac_g = ca.jacobian(ocp.g, ocp.z)
        qp_data = ca.Function(
            "morphing_qp_data",
            [ocp.z, ocp.p],
            [hessian, ca.gradient(ocp.objective, ocp.z), jac_g, ocp.g],
            ["z", "p"],
            ["h", "grad", "jac_g", "g"],
        )
        functions = [qp_data, _fg_function(ocp)]
        if options.compile:
            try:
                functions = compiled_functions("morphing_sqp_gn", functions, options.cache_dir)
            except (CompilationError, RuntimeError) as exc:
                _LOG.warning("sqp: compiled code unavailable (%s); using the SX VM", exc)
        self._qp_data, fg = functions
        self._evaluate = _Evaluator(fg)
        self._qp = ca.conic(
            "morphing_qp",
            "hpipm",
            {"h": hessian.sparsity(), "a": jac_g.sparsity()},
            {
                "N": ocp.horizon,
                "nx": ocp.nx,
                "nu": ocp.nu,
                "ng": ocp.ng,
                "hpipm.iter_max": 100,
                "error_on_fail": False,
                "print_problem": False,
            },
        )

    def solve(self, data: ProblemInstance) -> SolverResult:
        started = time.perf_counter()
        z = np.array(data.z0, dtype=float)  # x_0's equal bounds are met by the first step
        lam = np.array(data.lam_g0, dtype=float)
        lam_z = np.array(data.lam_z0, dtype=float)
        scale = 1.0 + np.abs(z)
        status, converged, iterations = "max_iter", False, 0
        for iterations in range(1, self.max_iter + 1):  # noqa: B007 (used after the loop)
            h, grad, jac, g = self._qp_data(z, data.p)
            g = np.asarray(g, dtype=float).ravel()
            sol = self._qp(
                h=h,
                g=grad,
                a=jac,
                lba=data.lbg - g,
                uba=data.ubg - g,
                lbx=data.lbz - z,
                ubx=data.ubz - z,
            )
            dz = np.asarray(sol["x"], dtype=float).ravel()
            if not np.all(np.isfinite(dz)):
                status = f"qp_failed({self._qp.stats().get('return_status', '?')})"
                break
            z = z + dz
            lam = np.asarray(sol["lam_a"], dtype=float).ravel()
            lam_z = np.asarray(sol["lam_x"], dtype=float).ravel()
            if np.max(np.abs(dz) / scale) <= self.options.tol:
                status, converged = "converged", True
                break
            if time.perf_counter() - started > self.options.max_time_s:
                status = "time_limit"
                break
        cost, violation = self._evaluate(z, data)
        finite = bool(np.all(np.isfinite(z))) and math.isfinite(cost)
        if not finite:
            status, converged = "non_finite", False
        elif self.name == "rti" and not converged and status == "max_iter":
            status = "rti_step"
        # An unconverged but feasible iterate is an RTI-grade plan: executable.
        limit = (
            self.options.usable_infeasibility
            if converged
            else self.options.rti_usable_infeasibility
        )
        usable = finite and violation <= limit and not status.startswith("qp_failed")
        return SolverResult(
            z=z,
            lam_g=lam,
            lam_z=lam_z,
            status=status,
            converged=converged,
            usable=usable,
            iterations=iterations,
            solve_time_s=time.perf_counter() - started,
            cost=cost,
            infeasibility=violation,
        )


def make_backend(name: str, ocp: MorphingOcp, options: SolverOptions):
    """The back-end called ``name`` (one of :data:`SOLVERS`)."""
    if name == "sqp":
        return SqpBackend(ocp, options)
    if name == "rti":
        return SqpBackend(ocp, options, max_iter=1)
    if name in ("ipopt", "fatrop"):
        return NlpBackend(ocp, name, options)
    if name == "condensed_sqp":
        from splitter_mpc.core.condensed_sqp import CondensedSqpBackend  # imports this module

        return CondensedSqpBackend(ocp, options)
    raise ValueError(f"unknown solver {name!r}; use one of {SOLVERS}")
