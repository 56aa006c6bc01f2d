"""Time integrators over the phase-space system interface (see `inertia.ode.system`).

References
----------
- Witkin & Baraff (2001), *Physically Based Modeling*, "Differential Equation Basics":
  explicit Euler, midpoint, the fourth-order Runge-Kutta method, adaptive step size.
- Dormand, J. R. & Prince, P. J. (1980), "A family of embedded Runge-Kutta formulae",
  J. Comput. Appl. Math. 6(1): the ``rk45`` coefficients (5th order with a 4th-order error
  estimate); step control after Hairer, Norsett & Wanner, *Solving ODEs I*, II.4.
- Verlet, L. (1967), Phys. Rev. 159: position Verlet (Stormer's method); Swope et al. (1982),
  J. Chem. Phys. 76: velocity Verlet; Hairer, Lubich & Wanner (2003), "Geometric numerical
  integration illustrated by the Stormer-Verlet method", Acta Numerica: leapfrog splittings.
- Baraff, D. & Witkin, A. (1998), "Large steps in cloth simulation", SIGGRAPH: linearised
  backward Euler solved by (filtered, preconditioned) conjugate gradients.

Every integrator advances any system that follows the interface; scratch buffers are
allocated once, when the integrator is built.

Limitations
-----------
- The symplectic methods (semi-implicit Euler, Verlet family) and implicit Euler need a
  second-order system; first-order systems (Tracers) take euler, midpoint, rk4 or rk45.
- With velocity-dependent forces the Verlet family evaluates the force with a predicted
  velocity (second-order accurate); it is then no longer exactly symplectic.
- ``implicit_euler`` linearises once per step (one Newton iteration) and treats forces that
  provide no Jacobian explicitly; spring Jacobians drop the transverse term of compressed
  springs to keep the matrix definite (Choi & Ko 2002).
"""

from __future__ import annotations

import numpy as np

from . import kernels as K

__all__ = ["Integrator", "available", "create", "register"]

_REGISTRY: dict[str, type["Integrator"]] = {}


def register(cls):
    """Class decorator: make an integrator selectable by its ``name``."""
    _REGISTRY[cls.name] = cls
    return cls


def available() -> list[str]:
    """Names of the integrators, in the order they were registered."""
    return list(_REGISTRY)


def create(name: str, system, **options) -> "Integrator":
    """Build the integrator called `name` for `system`."""
    if isinstance(name, Integrator):
        return name
    if name not in _REGISTRY:
        raise ValueError(f"integrator must be one of {available()}; got {name!r}")
    return _REGISTRY[name](system, **options)


class Integrator:
    """Base class: advances ``system.state`` in place by ``step(t, dt)``.

    Attributes: ``name``, ``order`` (global order of accuracy), ``symplectic``,
    ``second_order_only`` (needs y = [x, v]), ``fused_step`` (the system's fused method the
    step tries first, or None).
    """

    name = "base"
    order = 0
    symplectic = False
    second_order_only = False
    fused_step = None  # the system's fused method this integrator tries first ("kick_drift", "rk4")

    def __init__(self, system, **options):
        if options:
            raise ValueError(f"integrator {self.name!r} takes no options named {sorted(options)}")
        if self.second_order_only and not getattr(system, "second_order", False):
            first_order = [n for n, c in _REGISTRY.items() if not c.second_order_only]
            raise ValueError(
                f"integrator {self.name!r} needs a second-order system (positions and velocities); "
                f"{type(system).__name__} is first order: use one of {first_order}")
        self.system = system
        self.size = system.state.shape[0]

    def step(self, t: float, dt: float) -> None:  # pragma: no cover
        raise NotImplementedError

    def reset(self) -> None:
        """Forget any history kept between steps (multistep and cached-force methods)."""

    def get_state(self) -> dict:
        return {}

    def set_state(self, state: dict) -> None:
        self.reset()

    # helpers for second-order systems: flat views of x and v inside a state vector
    def _split(self, y):
        n = self.system.position_size
        return y[:n], y[n:]


@register
class ExplicitEuler(Integrator):
    """y_{n+1} = y_n + h f(y_n, t_n). First order; energy of an oscillator grows by (1 + w^2 h^2) per step."""

    name, order = "euler", 1

    def __init__(self, system, **options):
        super().__init__(system, **options)
        self.k = np.zeros(self.size)

    def step(self, t, dt):
        y = self.system.state
        self.system.derivative(y, t, self.k)
        K.axpy_inplace(y, self.k, dt)


@register
class Midpoint(Integrator):
    """y_{n+1} = y_n + h f(y_n + h/2 f(y_n), t_n + h/2). Second order."""

    name, order = "midpoint", 2

    def __init__(self, system, **options):
        super().__init__(system, **options)
        self.k = np.zeros(self.size)
        self.y_mid = np.zeros(self.size)

    def step(self, t, dt):
        y, k = self.system.state, self.k
        self.system.derivative(y, t, k)
        K.axpy_into(y, k, 0.5 * dt, self.y_mid)
        self.system.derivative(self.y_mid, t + 0.5 * dt, k)
        K.axpy_inplace(y, k, dt)


@register
class RK4(Integrator):
    """Classical fourth-order Runge-Kutta."""

    name, order = "rk4", 4
    fused_step = "rk4"

    def __init__(self, system, **options):
        super().__init__(system, **options)
        self.k = np.zeros((4, self.size))
        self.y_stage = np.zeros(self.size)

    def step(self, t, dt):
        s, y, ys = self.system, self.system.state, self.y_stage
        if getattr(s, "fused_rk4", None) is not None and s.fused_rk4(t, dt):
            return
        k1, k2, k3, k4 = self.k
        s.derivative(y, t, k1)
        K.axpy_into(y, k1, 0.5 * dt, ys)
        s.derivative(ys, t + 0.5 * dt, k2)
        K.axpy_into(y, k2, 0.5 * dt, ys)
        s.derivative(ys, t + 0.5 * dt, k3)
        K.axpy_into(y, k3, dt, ys)
        s.derivative(ys, t + dt, k4)
        K.rk4_finish(y, k1, k2, k3, k4, dt)


# Dormand-Prince 5(4) tableau.
_DP_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_DP_A = np.zeros((7, 7))
_DP_A[1, :1] = [1 / 5]
_DP_A[2, :2] = [3 / 40, 9 / 40]
_DP_A[3, :3] = [44 / 45, -56 / 15, 32 / 9]
_DP_A[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
_DP_A[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
_DP_A[6, :6] = [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]
# error weights: 5th-order weights (row 6) minus the embedded 4th-order weights
_DP_E = _DP_A[6] - np.array([5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200,
                             187 / 2100, 1 / 40])


@register
class RK45(Integrator):
    """Adaptive Dormand-Prince 5(4) with error control.

    ``step(t, dt)`` covers [t, t + dt] with as many internal steps as the tolerance needs
    (the fixed simulation step is an upper bound on the internal one).

    Options: ``rtol`` (1e-6 default; 1e-3..1e-10), ``atol`` (1e-9 default), ``max_substeps``
    (100000 per call). Counters ``accepted_steps`` and ``rejected_steps`` accumulate.
    """

    name, order = "rk45", 5

    def __init__(self, system, *, rtol=1e-6, atol=1e-9, max_substeps=100_000, **options):
        super().__init__(system, **options)
        if not (rtol > 0 and atol >= 0):
            raise ValueError(f"rk45 needs rtol > 0 and atol >= 0; got rtol={rtol}, atol={atol}")
        self.rtol, self.atol, self.max_substeps = float(rtol), float(atol), int(max_substeps)
        self.k = np.zeros((7, self.size))
        self.y_stage = np.zeros(self.size)
        self.y_new = np.zeros(self.size)
        self.err = np.zeros(self.size)
        self.zero = np.zeros(self.size)
        self.h = None  # internal step suggestion carried between calls
        self.k1_valid = False  # first-same-as-last: k[0] holds f(y, t) of the current state
        self.revision = None
        self.accepted_steps = 0
        self.rejected_steps = 0

    def reset(self):
        self.h = None
        self.k1_valid = False

    def get_state(self):
        return {"h": self.h, "accepted": self.accepted_steps, "rejected": self.rejected_steps}

    def set_state(self, state):
        self.reset()
        self.h = state["h"]
        self.accepted_steps, self.rejected_steps = state["accepted"], state["rejected"]

    def step(self, t, dt):
        s, y, k = self.system, self.system.state, self.k
        if self.revision != s.state_revision:
            self.k1_valid = False  # someone else changed the state: f(y) must be re-evaluated
            self.revision = s.state_revision
        t_end = t + dt
        h_try = dt if self.h is None else min(self.h, dt)
        for _ in range(self.max_substeps):
            remaining = t_end - t
            if remaining <= 1e-12 * dt:
                return
            last = h_try >= remaining * (1.0 - 1e-12)
            h = remaining if last else h_try
            if not self.k1_valid:
                s.derivative(y, t, k[0])
                self.k1_valid = True
            for i in range(1, 7):
                K.rk_stage(y, k, _DP_A[i], i, h, self.y_stage)
                s.derivative(self.y_stage, t + _DP_C[i] * h, k[i])
            # y_stage now holds the 5th-order solution; err = sum_j e_j k_j (times h in the norm)
            K.rk_stage(self.zero, k, _DP_E, 7, 1.0, self.err)
            error = K.scaled_error_norm(y, self.y_stage, self.err, self.atol, self.rtol, h)
            factor = 5.0 if error == 0.0 else min(5.0, max(0.2, 0.9 * error ** -0.2))
            if error <= 1.0:
                y[:] = self.y_stage
                k[0][:] = k[6]  # first same as last
                t = t_end if last else t + h
                self.accepted_steps += 1
                # a step shortened to land on t_end says little about the next one
                h_try = max(h * factor, h_try) if last else h * factor
            else:
                self.rejected_steps += 1
                h_try = h * factor
            self.h = h_try
        raise RuntimeError(f"rk45 needed more than {self.max_substeps} internal steps in one step "
                           f"of dt={dt}; loosen rtol/atol or use implicit_euler for stiff systems")


class _CachedAcceleration(Integrator):
    """Second-order methods that reuse the acceleration of the previous step.

    The cache is valid only while nobody else changed the state (``state_revision``) and the
    step continues from the time the cache was computed for.
    """

    second_order_only = True

    def __init__(self, system, **options):
        super().__init__(system, **options)
        n = system.position_size
        self.a = np.zeros(n)
        self.a_prev = np.zeros(n)
        self.scratch_x = np.zeros(n)
        self.scratch_v = np.zeros(n)
        self.cache_time = None
        self.cache_revision = None

    def reset(self):
        self.cache_time = None

    def _cache_valid(self, t):
        return (self.cache_time is not None and self.cache_revision == self.system.state_revision
                and abs(self.cache_time - t) <= 1e-12 * max(1.0, abs(t)))

    def _remember(self, t):
        self.cache_time = t
        self.cache_revision = self.system.state_revision

    def get_state(self):
        return {"a_prev": self.a_prev.copy(), "cache_time": self.cache_time,
                "cache_revision": self.cache_revision}

    def set_state(self, state):
        self.a_prev[:] = state["a_prev"]
        self.cache_time = state["cache_time"]
        self.cache_revision = state["cache_revision"]


@register
class SemiImplicitEuler(Integrator):
    """Symplectic Euler: v_{n+1} = v_n + h a(x_n, v_n); x_{n+1} = x_n + h v_{n+1}. First order.

    Uses the system's fused ``kick_drift`` when it offers one (a single pass over memory).
    """

    name, order, symplectic, second_order_only = "semi_implicit_euler", 1, True, True
    fused_step = "kick_drift"

    def __init__(self, system, **options):
        super().__init__(system, **options)
        self.a = np.zeros(system.position_size)

    def step(self, t, dt):
        s = self.system
        if getattr(s, "kick_drift", None) is not None and s.kick_drift(t, dt):
            return
        x, v = self._split(s.state)
        s.acceleration(x, v, t, self.a)
        K.kick_drift(x, v, self.a, dt)


@register
class PositionVerlet(_CachedAcceleration):
    """Position Verlet (Stormer): x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n. Second order, symplectic.

    Keeps the two latest positions; needs a constant dt (a change of dt restarts it). Starts from
    (x0, v0) with the Taylor step x_1 = x0 + h v0 + h^2 a0 / 2. The velocity in the state is the
    second-order estimate v_{n+1} = (x_{n+1} - x_n)/h + h a_n / 2.
    """

    name, order, symplectic = "verlet", 2, True

    def __init__(self, system, **options):
        super().__init__(system, **options)
        self.x_prev = np.zeros(system.position_size)
        self.dt = None

    def reset(self):
        super().reset()
        self.dt = None

    def get_state(self):
        state = super().get_state()
        state.update(x_prev=self.x_prev.copy(), dt=self.dt)
        return state

    def set_state(self, state):
        super().set_state(state)
        self.x_prev[:] = state["x_prev"]
        self.dt = state["dt"]

    def step(self, t, dt):
        s = self.system
        x, v = self._split(s.state)
        restart = not self._cache_valid(t) or self.dt is None or abs(self.dt - dt) > 1e-12 * dt
        s.acceleration(x, v, t, self.a)
        if restart:
            # x_{-1} chosen so that the Verlet update reproduces the Taylor start-up step:
            # 2 x0 - x_{-1} + h^2 a0 = x0 + h v0 + h^2 a0 / 2  =>  x_{-1} = x0 - h v0 + h^2 a0 / 2
            self.x_prev[:] = x - dt * v + 0.5 * dt * dt * self.a
            self.dt = dt
        K.verlet_advance(x, self.x_prev, v, self.a, self.a_prev, dt)
        self._remember(t + dt)


@register
class VelocityVerlet(_CachedAcceleration):
    """Velocity Verlet (kick-drift-kick). Second order, symplectic for position-only forces.

    v_{n+1/2} = v_n + h/2 a_n; x_{n+1} = x_n + h v_{n+1/2}; v_{n+1} = v_{n+1/2} + h/2 a_{n+1},
    with a_{n+1} evaluated at the predicted velocity v_{n+1/2} + h/2 a_n.
    One force evaluation per step (a_{n+1} is reused as the next a_n).
    """

    name, order, symplectic = "velocity_verlet", 2, True

    def step(self, t, dt):
        s = self.system
        x, v = self._split(s.state)
        a, v_pred = self.a_prev, self.scratch_v
        if not self._cache_valid(t):
            s.acceleration(x, v, t, a)
        K.axpy_inplace(v, a, 0.5 * dt)         # kick to the half step
        K.axpy_inplace(x, v, dt)               # drift
        K.axpy_into(v, a, 0.5 * dt, v_pred)    # predicted v_{n+1} for velocity-dependent forces
        s.acceleration(x, v_pred, t + dt, a)   # a_{n+1}
        K.axpy_inplace(v, a, 0.5 * dt)         # second kick
        self._remember(t + dt)


@register
class Leapfrog(_CachedAcceleration):
    """Leapfrog in drift-kick-drift form. Second order, symplectic for position-only forces.

    x_{n+1/2} = x_n + h/2 v_n; v_{n+1} = v_n + h a(x_{n+1/2}); x_{n+1} = x_{n+1/2} + h/2 v_{n+1}.
    Velocity-dependent forces see the predicted v_{n+1/2} = v_n + h/2 a_{n-1/2}.
    """

    name, order, symplectic = "leapfrog", 2, True

    def step(self, t, dt):
        s = self.system
        x, v = self._split(s.state)
        a, v_half = self.a_prev, self.scratch_v
        if not self._cache_valid(t):
            s.acceleration(x, v, t, a)  # start-up: a at t stands in for a_{-1/2}
        K.axpy_inplace(x, v, 0.5 * dt)
        K.axpy_into(v, a, 0.5 * dt, v_half)
        s.acceleration(x, v_half, t + 0.5 * dt, a)
        K.axpy_inplace(v, a, dt)
        K.axpy_inplace(x, v, 0.5 * dt)
        self._remember(t + dt)


@register
class ImplicitEuler(Integrator):
    """Linearised backward Euler (Baraff & Witkin 1998). First order, unconditionally stable for springs.

    Solves (M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0), then v += dv, x += h v,
    by block-Jacobi preconditioned conjugate gradients with pinned particles filtered out.

    Options: ``cg_tolerance`` (relative residual, 1e-8 default; 1e-4 is plenty for visuals),
    ``cg_max_iterations`` (1000). ``last_cg_iterations`` reports the latest solve.
    """

    name, order, second_order_only = "implicit_euler", 1, True

    def __init__(self, system, *, cg_tolerance=1e-8, cg_max_iterations=1000, **options):
        super().__init__(system, **options)
        if not hasattr(system, "evaluate_with_jacobians"):
            raise ValueError(f"implicit_euler needs a system that provides force Jacobians; "
                             f"{type(system).__name__} does not")
        if not (cg_tolerance > 0):
            raise ValueError(f"cg_tolerance must be > 0; got {cg_tolerance}")
        self.cg_tolerance, self.cg_max_iterations = float(cg_tolerance), int(cg_max_iterations)
        n = system.position_size
        self.f = np.zeros(n)
        self.rhs = np.zeros(n)
        self.dv = np.zeros(n)
        self.cg_scratch = [np.zeros(n) for _ in range(4)]
        self.inv_blocks = None
        self.partial = np.zeros(K.REDUCTION_CHUNKS)
        self.pattern = None
        self.last_cg_iterations = 0

    def _ensure_pattern(self):
        pattern = self.system.jacobian_pattern
        if pattern is not self.pattern:
            had_pattern = self.pattern is not None
            self.pattern = pattern
            d = pattern.block_dim
            self.dfdx = np.zeros((pattern.nnz, d, d))
            self.dfdv = np.zeros((pattern.nnz, d, d))
            self.matrix = np.zeros((pattern.nnz, d, d))
            self.inv_blocks = np.zeros((pattern.row_start.shape[0] - 1, d, d))
            if had_pattern:
                self.dv[:] = 0.0  # forces changed: the previous solution is no guess for the new system
        return pattern

    def reset(self):
        self.dv[:] = 0.0

    def get_state(self):
        return {"dv": self.dv.copy()}

    def set_state(self, state):
        self.dv[:] = state["dv"]

    def step(self, t, dt):
        s = self.system
        p = self._ensure_pattern()
        x, v = self._split(s.state)
        s.evaluate_with_jacobians(x, v, t, self.f, self.dfdx, self.dfdv)
        K.implicit_euler_matrix(s.node_mass, p.diag_slot, self.dfdx, self.dfdv, dt, self.matrix)
        # rhs = h f0 + h^2 (df/dx) v0
        K.bsr_matvec(p.row_start, p.columns, self.dfdx, v, self.rhs)
        K.axpy_into(self.f, self.rhs, dt, self.rhs)
        self.rhs *= dt
        r, z, pp, q = self.cg_scratch
        # the previous step's dv is the initial guess (it is part of the saved state)
        self.last_cg_iterations = K.pcg_solve(
            p.row_start, p.columns, self.matrix, p.diag_slot, self.rhs, s.node_free, self.dv,
            self.cg_tolerance, self.cg_max_iterations, r, z, pp, q, self.inv_blocks, self.partial)
        K.axpy_inplace(v, self.dv, 1.0)
        K.axpy_inplace(x, v, dt)
