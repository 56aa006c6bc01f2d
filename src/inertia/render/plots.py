"""Energy and momentum over time, as a PNG (matplotlib, Agg backend: no display needed).

`plot_energy` draws two panels sharing the time axis:

top     kinetic energy K, potential energy U and their sum E = K + U (when U is given), with the
        relative drift of E, (E(t_end) - E(t_0)) / |E(t_0)|, in the legend;
bottom  linear momentum: its components (when given as (F, D)) and its magnitude.

`energy_from_states` computes K = sum_i m_i |v_i|^2 / 2, P = sum_i m_i v_i and, for uniform
gravity g, U = -sum_i m_i g . x_i, over the active particles of each frame, when the run did
not record them (a recorder may store the per-frame fields ``kinetic_energy``,
``potential_energy`` and ``momentum``, which take precedence).

`system_series` reads what a run recorded per system (the particle groups, the rigid bodies'
``diag/bodies/*`` and each fluid's ``diag/<name>/*`` fields, written by `inertia.world.Run` from
`World.system_diagnostics`) into `SystemSeries`, and `plot_systems` draws one row per system: its
energies on the left, and on the right its momentum (particles, bodies) or what a fluid must keep
(mass or volume) with its incompressibility error. Energy a scene removes on purpose (inelastic
contacts, friction, damping, viscosity) is labelled as dissipated, a gain as gained.

Requires matplotlib (``pip install inertia[cli]``). Written atomically.

Limitations: potential energy of springs and other forces is known only when recorded.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_path

__all__ = ["plot_energy", "energy_from_states", "plot_states_energy", "SystemSeries", "system_series", "plot_systems"]


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


@dataclass
class SystemSeries:
    """The curves of one system over a run: ``name`` (``"particles"``, ``"bodies"`` or a fluid's
    name), ``kind`` (``"particles"``, ``"tracers"``, ``"bodies"``, ``"sph"``, ``"smoke"``, ``"liquid"``),
    ``energy`` {label: (F,) J}, ``right`` {label: (F,) values} drawn on the right panel with
    ``right_unit`` (its y label; tracers: their mean and largest speed), ``secondary`` {label: (F,)} on a second axis with
    ``secondary_unit``, and ``dissipation``: what removes energy on purpose in this system."""

    name: str
    kind: str
    energy: dict = field(default_factory=dict)
    right: dict = field(default_factory=dict)
    right_unit: str = ""
    secondary: dict = field(default_factory=dict)
    secondary_unit: str = ""
    dissipation: str = ""

    @property
    def empty(self) -> bool:
        """True when no curve holds a finite value."""
        return not any(np.isfinite(np.asarray(v, np.float64)).any() for v in
                       (*self.energy.values(), *self.right.values(), *self.secondary.values()))


def _momentum_curves(p) -> dict:
    p = np.asarray(p, np.float64)
    if p.ndim == 1:
        return {"|p|": p}
    out = {f"p{'xyz'[c]}": p[:, c] for c in range(p.shape[1])}
    out["|p|"] = np.linalg.norm(p, axis=1)
    return out


def system_series(states) -> list[SystemSeries]:
    """One `SystemSeries` per system a run recorded (see the module docstring); systems with no
    finite value are left out."""
    fields = states.fields
    out: list[SystemSeries] = []
    kinds = list(states.metadata.get("group_kinds") or [])
    has_particles = states.particle_count > 0 and (not kinds or "particles" in kinds)
    if has_particles:
        kinetic = fields.get("kinetic_energy")
        if kinetic is not None and np.isfinite(kinetic).any():
            series = {"kinetic": np.asarray(kinetic, np.float64), "momentum": fields.get("momentum"),
                      "potential": fields.get("potential_energy")}
        elif states.velocities is not None:
            series = energy_from_states(states)
        else:
            series = {}
        if series.get("kinetic") is not None:
            energy = {"kinetic K": series["kinetic"]}
            if series.get("potential") is not None and np.isfinite(series["potential"]).any():
                energy["potential U"] = np.asarray(series["potential"], np.float64)
                energy["total E = K + U"] = energy["kinetic K"] + energy["potential U"]
            right = {} if series.get("momentum") is None else _momentum_curves(series["momentum"])
            out.append(SystemSeries("particles", "particles", energy, right, "momentum [kg m/s]",
                                    dissipation="restitution < 1, friction and damping"))
    if states.particle_count > 0 and "tracers" in kinds and states.velocities is not None:
        groups = states.groups()
        pick = np.isin(groups, [i for i, k in enumerate(kinds) if k == "tracers"]) if groups is not None else slice(None)
        speed = np.linalg.norm(np.asarray(states.velocities, np.float64)[:, pick], axis=2)  # (F, M)
        out.append(SystemSeries("tracers", "tracers", {}, {"mean speed": np.nanmean(speed, axis=1),
                                                          "max speed": np.nanmax(speed, axis=1)}, "speed [m/s]"))
    if "diag/bodies/kinetic_energy" in fields:
        k = np.asarray(fields["diag/bodies/kinetic_energy"], np.float64)
        u = np.asarray(fields.get("diag/bodies/potential_energy", np.full_like(k, np.nan)), np.float64)
        energy = {"kinetic K": k, "potential U": u, "total E = K + U": k + u}
        right = _momentum_curves(fields["diag/bodies/momentum"]) if "diag/bodies/momentum" in fields else {}
        out.append(SystemSeries("bodies", "bodies", energy, right, "momentum [kg m/s]",
                                dissipation="restitution < 1, friction, contact softness and damping"))
    for name in states.metadata.get("fluids") or []:
        key = f"diag/{name}/"
        if key + "kinetic_energy" not in fields:
            continue
        energy = {"kinetic K": np.asarray(fields[key + "kinetic_energy"], np.float64)}
        get = lambda q: np.asarray(fields[key + q], np.float64)  # noqa: E731
        if key + "density_error" in fields:
            series = SystemSeries(name, "sph", energy, {"mass": get("mass")}, "mass [kg]",
                                  {"density error": 100.0 * get("density_error")}, "density error [%]",
                                  dissipation="viscosity")
        elif key + "volume" in fields:
            series = SystemSeries(name, "liquid", energy, {"volume": get("volume")}, "volume [m^3]",
                                  dissipation="viscosity and the grid's transfer")
        else:
            series = SystemSeries(name, "smoke", energy, {"max |div u|": get("divergence")}, "divergence [1/s]",
                                  dissipation="viscosity and advection")
        out.append(series)
    return [s for s in out if not s.empty]


def _change_label(total: np.ndarray) -> str:
    """' (12.3% dissipated)' or ' (+0.4% gained)' from the first to the last finite value."""
    finite = total[np.isfinite(total)]
    if finite.size < 2 or finite[0] == 0:
        return ""
    change = 100.0 * (finite[-1] - finite[0]) / abs(finite[0])
    return f" ({-change:.3g}% dissipated)" if change < 0 else f" (+{change:.3g}% gained)"


def plot_systems(times, systems: list[SystemSeries], path: str | os.PathLike = "energy.png", *,
                 title: str | None = None, dpi: int = 110) -> Path:
    """One row per system: energies [J] left (the total labelled with the share dissipated), and the
    system's ``right`` curves right (with ``secondary`` on a second axis). Returns the path."""
    if not systems:
        raise ValueError("plot_systems: no system with recorded values to plot")
    Figure = _pyplot()
    times = np.asarray(times, dtype=np.float64)
    rows = len(systems)
    figure = Figure(figsize=(10.0, 2.7 * rows + 0.7), dpi=dpi, layout="constrained")
    axes = figure.subplots(rows, 2, sharex=True, squeeze=False)
    palette = ("#1f77b4", "#ff7f0e", "black", "#2ca02c", "#d62728", "#9467bd")
    for row, system in enumerate(systems):
        ax = axes[row, 0]
        for i, (label, values) in enumerate(system.energy.items()):
            total = label.startswith("total")
            if total:
                label += _change_label(np.asarray(values, np.float64))
            ax.plot(times, values, label=label, color=palette[i % len(palette)], lw=1.8 if total else 1.3)
        if not system.energy:
            ax.text(0.5, 0.5, "massless tracers: no energy", ha="center", va="center", transform=ax.transAxes)
        ax.set_ylabel("energy [J]")
        heading = f"{system.name}: energy"
        if system.dissipation:
            heading += f" (dissipated by {system.dissipation})"
        ax.set_title(heading, fontsize="medium", loc="left")
        ax.grid(True, alpha=0.3)
        if system.energy:
            ax.legend(loc="best", fontsize="small")
        ax = axes[row, 1]
        for i, (label, values) in enumerate(system.right.items()):
            ax.plot(times, values, label=label, lw=1.8 if label.startswith("|") else 1.2,
                    color="black" if label.startswith("|") else palette[(i + 3) % len(palette)])
        ax.set_ylabel(system.right_unit)
        ax.set_title(f"{system.name}: {system.right_unit.split(' [')[0]}", fontsize="medium", loc="left")
        ax.grid(True, alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        if system.secondary:
            twin = ax.twinx()
            for label, values in system.secondary.items():
                twin.plot(times, values, label=label, color="#d62728", lw=1.0, ls="--")
            twin.set_ylabel(system.secondary_unit)
            h2, l2 = twin.get_legend_handles_labels()
            handles, labels = handles + h2, labels + l2
        if handles:
            ax.legend(handles, labels, loc="best", fontsize="small")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    if title:
        figure.suptitle(title)
    path = Path(path)
    with atomic_path(path) as temp:
        figure.savefig(temp, format=path.suffix.lstrip(".").lower() or "png")
    return path
