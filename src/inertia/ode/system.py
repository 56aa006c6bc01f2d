"""The phase-space system interface that every integrator advances.

References
----------
Witkin, A. & Baraff, D. (1997/2001). *Physically Based Modeling: Principles and Practice*,
SIGGRAPH course notes, "Differential Equation Basics" and "Particle System Dynamics".

A system owns its whole state as one contiguous float64 vector ``state`` (``y``) and exposes

``derivative(y, t, out)``
    fills ``out`` with dy/dt. ``y`` may be the system's own state or an integrator's scratch
    stage; the system must read only ``y``.

Second-order systems (``second_order = True``) lay the state out as ``y = [x, v]`` with
``position_size`` entries each, and also provide

``acceleration(x, v, t, out)``
    fills ``out`` with dv/dt for flat position and velocity arrays (used by the symplectic
    integrators, which update positions and velocities separately).

Optional capabilities, probed by the integrators that can use them:

``kick_drift(t, dt)``
    a fused semi-implicit Euler step over the system's own state; returns False when the
    system cannot fuse its current forces (the integrator then falls back to the generic path).
``fused_rk4(t, dt)``
    the same for the classical RK4 step (possible when every particle's ODE is independent).
``jacobian_pattern``, ``evaluate_with_jacobians(x, v, t, f, dfdx, dfdv)``, ``node_mass``
    the force and its block-sparse Jacobians, for ``implicit_euler``.

``state_revision`` is an integer bumped whenever something other than the integrator changes
the state (collision response, a restored checkpoint, an emitter spawning particles);
multistep integrators (position Verlet) restart their history when it changes.

``integrator_fused_step`` (set by ``Simulation.step`` before the step's stages begin) names the
fused method the integrator will try this step ("kick_drift", "rk4" or None), so a stage can
prepare to run inside it (the collision pass, see ``collision.particle_stage``).

``finite_revision`` is the divergence check's witness: the ``state_revision`` at which a fused
kernel, in the same pass that wrote the state, found every value finite (None: unknown).
``Simulation.step`` clears it before integrating and skips its own pass over the state when the
witness still matches after the stages; a stage that changes the state and knows that what it
wrote is finite calls ``state_modified(finite=True)`` to carry the witness over.

Limitations: constraints are not part of this interface; they are separate step stages.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PhaseSpaceSystem", "BlockSparsePattern"]


class PhaseSpaceSystem:
    """Base class documenting the interface (see the module docstring).

    Subclasses set ``state`` (1-D float64), ``second_order`` and, when second order,
    ``position_size``; they implement ``derivative`` and, when second order, ``acceleration``.
    """

    state: np.ndarray
    second_order: bool = False
    position_size: int = 0
    state_revision: int = 0
    integrator_fused_step: str | None = None
    finite_revision: int | None = None

    def derivative(self, y: np.ndarray, t: float, out: np.ndarray) -> None:  # pragma: no cover
        raise NotImplementedError

    def acceleration(self, x: np.ndarray, v: np.ndarray, t: float, out: np.ndarray) -> None:
        raise NotImplementedError  # pragma: no cover

    def state_modified(self, finite: bool = False) -> None:
        """Record that the state was changed outside an integrator step.

        finite=True: the caller knows the values it wrote are finite, so a finite state stays
        known to be finite (the divergence check's witness carries over)."""
        known = finite and self.finite_revision is not None and self.finite_revision == self.state_revision
        self.state_revision += 1
        self.finite_revision = self.state_revision if known else None

    # The optional capabilities default to "absent".
    def kick_drift(self, t: float, dt: float) -> bool:
        return False

    def fused_rk4(self, t: float, dt: float) -> bool:
        return False


@dataclass(frozen=True)
class BlockSparsePattern:
    """Sparsity of a block-sparse (BSR) matrix over nodes, with ``block_dim`` x ``block_dim`` blocks.

    row_start : (nodes + 1,) int64 -- row i's blocks occupy slots row_start[i]:row_start[i+1]
    columns   : (nnz,) int64       -- column node of each slot, sorted within a row
    diag_slot : (nodes,) int64     -- slot of the diagonal block (i, i)
    """

    row_start: np.ndarray
    columns: np.ndarray
    diag_slot: np.ndarray
    block_dim: int

    @property
    def nnz(self) -> int:
        return int(self.columns.shape[0])

    @classmethod
    def from_pairs(cls, node_count: int, pairs: np.ndarray, block_dim: int) -> "BlockSparsePattern":
        """Pattern holding every diagonal block and both (i, j), (j, i) for each pair."""
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        diag = np.arange(node_count, dtype=np.int64)
        rows = np.concatenate([diag, pairs[:, 0], pairs[:, 1]])
        cols = np.concatenate([diag, pairs[:, 1], pairs[:, 0]])
        keys = np.unique(rows * node_count + cols)
        rows, cols = keys // node_count, keys % node_count
        row_start = np.zeros(node_count + 1, dtype=np.int64)
        np.add.at(row_start, rows + 1, 1)
        row_start = np.cumsum(row_start)
        diag_slot = np.searchsorted(keys, diag * node_count + diag)
        return cls(row_start, np.ascontiguousarray(cols), diag_slot.astype(np.int64), block_dim)

    def slot_of(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Slot index of each block (rows[k], cols[k]); every block must be in the pattern."""
        n = self.row_start.shape[0] - 1
        keys_all = np.repeat(np.arange(n, dtype=np.int64), np.diff(self.row_start)) * n + self.columns
        keys = np.asarray(rows, dtype=np.int64) * n + np.asarray(cols, dtype=np.int64)
        slots = np.searchsorted(keys_all, keys)
        if keys.size and (np.any(slots >= keys_all.size) or np.any(keys_all[np.minimum(slots, keys_all.size - 1)] != keys)):
            raise ValueError("block not present in the Jacobian pattern")
        return slots.astype(np.int64)
