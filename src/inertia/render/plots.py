"""Energy and momentum over time, as a PNG (matplotlib, Agg backend: no display needed).

`plot_energy` draws two panels sharing the time axis:

top     kinetic energy K, potential energy U and their sum E = K + U (when U is given), with the
        relative drift of E, (E(t_end) - E(t_0)) / |E(t_0)|, in the legend;
bottom  linear momentum: its components (when given as (F, D)) and its magnitude.

`energy_from_states` computes K = sum_i m_i |v_i|^2 / 2, P = sum_i m_i v_i and, for uniform
gravity g, U = -sum_i m_i g . x_i, over the active particles of each frame, when the run did
not record them (a recorder may store the per-frame fields ``kinetic_energy``,
``potential_energy`` and ``momentum``, which take precedence).

Requires matplotlib (``pip install inertia[cli]``). Written atomically.

Limitations: potential energy of springs and other forces is known only when recorded.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_path

__all__ = ["plot_energy", "energy_from_states", "plot_states_energy"]


def _pyplot():
    try:
        import matplotlib
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError("plots need matplotlib: pip install inertia[cli]  (or: pip install matplotlib)") from error
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure


def plot_energy(
    times,
    kinetic=None,
    potential=None,
    momentum=None,
    path: str | os.PathLike = "energy.png",
    *,
    title: str | None = None,
    dpi: int = 120,
) -> Path:
    """Plot energy (top) and momentum (bottom) against time into ``path`` (PNG, SVG or PDF).

    times (F,) seconds; kinetic (F,) J; potential (F,) J or None; momentum (F,) or (F, D) kg m/s
    or None (then one panel). Returns the path.

    Also ``plot_energy(states, path)``: a `States` first, the path second, which is
    `plot_states_energy(states, path)` (recorded energies, else computed from velocities).
    """
    if hasattr(times, "positions") and hasattr(times, "times"):
        target = path if kinetic is None else kinetic
        return plot_states_energy(times, target, title=title)
    if kinetic is None:
        raise TypeError("plot_energy: kinetic energies are required (or pass a States first)")
    Figure = _pyplot()
    times = np.asarray(times, dtype=np.float64)
    kinetic = np.asarray(kinetic, dtype=np.float64)
    if kinetic.shape != times.shape:
        raise ValueError(f"plot_energy: kinetic must have the shape of times {times.shape}, got {kinetic.shape}")
    if potential is not None:
        potential = np.asarray(potential, dtype=np.float64)
        if potential.shape != times.shape:
            raise ValueError(f"plot_energy: potential must have the shape of times {times.shape}, got {potential.shape}")
    panels = 2 if momentum is not None else 1
    figure = Figure(figsize=(8.0, 3.0 * panels + 0.6), dpi=dpi, layout="constrained")
    axes = figure.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]

    # Energy.
    ax = axes[0]
    ax.plot(times, kinetic, label="kinetic K", color="#1f77b4", lw=1.4)
    if potential is not None:
        total = kinetic + potential
        ax.plot(times, potential, label="potential U", color="#ff7f0e", lw=1.4)
        drift = ""
        if total.size > 1 and total[0] != 0 and np.isfinite(total).all():
            drift = f" (drift {100.0 * (total[-1] - total[0]) / abs(total[0]):+.3g}%)"
        ax.plot(times, total, label=f"total E = K + U{drift}", color="black", lw=1.8)
    ax.set_ylabel("energy [J]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)

    # Momentum.
    if momentum is not None:
        p = np.asarray(momentum, dtype=np.float64)
        ax = axes[1]
        if p.ndim == 2:
            for c in range(p.shape[1]):
                ax.plot(times, p[:, c], label=f"p{'xyz'[c]}", lw=1.2)
            ax.plot(times, np.linalg.norm(p, axis=1), label="|p|", color="black", lw=1.8)
        elif p.shape == times.shape:
            ax.plot(times, p, label="|p|", color="black", lw=1.8)
        else:
            raise ValueError(f"plot_energy: momentum must be (F,) or (F, D) with F = {times.size}, got {p.shape}")
        ax.set_ylabel("momentum [kg m/s]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time [s]")

    path = Path(path)
    with atomic_path(path) as temp:
        figure.savefig(temp, format=path.suffix.lstrip(".").lower() or "png")
    return path


def energy_from_states(states, *, masses=None, gravity=None) -> dict[str, np.ndarray]:
    """Per-frame ``kinetic`` (F,), ``momentum`` (F, D) and, with ``gravity`` (D,), ``potential`` (F,).

    Recorded fields ``kinetic_energy``, ``potential_energy`` and ``momentum`` are used when
    present. ``masses``: (N,) or scalar, default the static ``mass`` of the states, else 1.
    Infinite masses (pinned particles) are left out.
    """
    result: dict[str, np.ndarray] = {}
    m = masses if masses is not None else states.static.get("mass", 1.0)
    m = np.broadcast_to(np.asarray(m, dtype=np.float64), (states.particle_count,))
    weight = np.where(np.isfinite(m), m, 0.0)
    active = states.fields.get("active")
    w = np.broadcast_to(weight, (states.frame_count, states.particle_count))
    if active is not None:
        w = w * active
    if "kinetic_energy" in states.fields:
        result["kinetic"] = np.asarray(states.fields["kinetic_energy"], dtype=np.float64)
    elif states.velocities is not None:
        v2 = np.einsum("fnd,fnd->fn", states.velocities, states.velocities)
        result["kinetic"] = 0.5 * np.einsum("fn,fn->f", w, v2)
    if "momentum" in states.fields:
        result["momentum"] = np.asarray(states.fields["momentum"], dtype=np.float64)
    elif states.velocities is not None:
        result["momentum"] = np.einsum("fn,fnd->fd", w, states.velocities)
    if "potential_energy" in states.fields:
        result["potential"] = np.asarray(states.fields["potential_energy"], dtype=np.float64)
    elif gravity is not None:
        g = np.asarray(gravity, dtype=np.float64)
        result["potential"] = -np.einsum("fn,fnd,d->f", w, states.positions, g)
    return result


def plot_states_energy(states, path: str | os.PathLike, *, masses=None, gravity=None, title: str | None = None) -> Path:
    """`energy_from_states` then `plot_energy` for a whole run."""
    series = energy_from_states(states, masses=masses, gravity=gravity)
    if "kinetic" not in series:
        raise ValueError("plot_states_energy: the states have no velocities and no recorded kinetic_energy")
    return plot_energy(states.times, series["kinetic"], series.get("potential"), series.get("momentum"), path, title=title)
