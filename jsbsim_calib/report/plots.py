"""Plots for reports. Every function takes an optional ``ax`` and returns the figure.

Matplotlib's Agg backend only: no display needed.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import pandas as pd  # noqa: E402

from ..calibration.diagnose import REGRESSORS  # noqa: E402
from ..data.g1000.parse import G1000Log  # noqa: E402
from ..data.g1000.segments import Segment  # noqa: E402
from ..data.schemas import METRICS  # noqa: E402
from ..physics.atmosphere import kcas_from_kias, ktas_from_kcas, pressure_altitude_ft  # noqa: E402

STYLES = {"baseline": dict(color="tab:gray", ls="--", lw=1.2), "calibrated": dict(color="tab:blue", ls="-", lw=1.6),
          "thesis": dict(color="tab:orange", ls=":", lw=1.2)}


def _ax(ax, size=(6.4, 4.4)):
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=size, dpi=110)
    return fig, fig.add_subplot(111)


def _style(label: str) -> dict:
    return STYLES.get(label, dict(lw=1.4))


def _with_unit(metric: str) -> str:
    """A metric's axis text with its unit (every axis carries its unit)."""
    return f"{metric} [{METRICS[metric].unit}]"


PANELS_PER_ROW = 4          # a strip of more panels wraps to rows


def climb_vs_altitude(evals: Mapping[str, object], ax=None) -> Figure:
    """Rate of climb vs pressure altitude: data markers per temperature, one line per model."""
    fig, ax = _ax(ax)
    first = next(iter(evals.values()))
    f = first.dataset.frame
    temp_col = "oat_c" if "oat_c" in f else "temp_dev_c"
    temps = sorted(f[temp_col].unique())
    cmap = matplotlib.colormaps["coolwarm"]
    for k, T in enumerate(temps):
        c = cmap(k / max(1, len(temps) - 1))
        sel = f[temp_col] == T
        ax.plot(f.loc[sel, "pressure_alt_ft"], f.loc[sel, "roc_fpm"], "o", color=c, ms=5,
                label=f"POH {T:g} C" if temp_col == "oat_c" else f"POH ISA{T:+g}")
        for label, ev in evals.items():
            pts = [p for p, s in zip(ev.points, sel) if s]
            alt = [p.inputs["pressure_alt_ft"] for p in pts]
            roc = [p.model.get("roc_fpm", np.nan) for p in pts]
            st = _style(label)
            ax.plot(alt, roc, color=c, ls=st["ls"], lw=st["lw"])
    for label in evals:
        ax.plot([], [], color="k", ls=_style(label)["ls"], label=label)
    ax.set_xlabel("pressure altitude [ft]")
    ax.set_ylabel("rate of climb [ft/min]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Maximum rate of climb: POH vs model")
    return fig


def cruise_vs_speed(evals: Mapping[str, object], metric: str, ax=None) -> Figure:
    """A cruise metric vs KTAS, one colour per altitude: POH markers, model lines."""
    fig, ax = _ax(ax)
    first = next(iter(evals.values()))
    f = first.dataset.frame
    alts = sorted(f["pressure_alt_ft"].unique())
    cmap = matplotlib.colormaps["viridis"]
    for k, h in enumerate(alts):
        c = cmap(k / max(1, len(alts) - 1))
        sel = (f["pressure_alt_ft"] == h).to_numpy()
        ax.plot(f.loc[sel, "ktas"], f.loc[sel, metric], "o", color=c, ms=4, label=f"{h:,.0f} ft")
        for label, ev in evals.items():
            pts = [p for p, s in zip(ev.points, sel) if s]
            st = _style(label)
            ax.plot([p.inputs["ktas"] for p in pts], [p.model.get(metric, np.nan) for p in pts], color=c,
                    ls=st["ls"], lw=st["lw"])
    for label in evals:
        ax.plot([], [], color="k", ls=_style(label)["ls"], label=label)
    ax.set_xlabel("true airspeed [kt]")
    ax.set_ylabel(f"{metric} [{METRICS[metric].unit}]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"Cruise {METRICS[metric].doc}: POH vs model")
    return fig


def _band_bars(ax, x: np.ndarray, y: np.ndarray, ok: np.ndarray, band: np.ndarray | None, **style) -> None:
    """Each point's 95 % prediction band as an error bar (points drawn and with a finite band)."""
    if band is None:
        return
    b = ok & np.isfinite(band)
    if b.any():
        ax.errorbar(x[b], y[b], yerr=band[b], fmt="none", **style)


def parity(evals: Mapping[str, object], metric: str, ax=None, bands: Mapping[str, np.ndarray] | None = None) -> Figure:
    """Model vs data for one metric, with the tolerance band; ``bands``: per label, the 95 %
    prediction band of each point (error bars)."""
    fig, ax = _ax(ax, (4.6, 4.4))
    lo, hi = np.inf, -np.inf
    for label, ev in evals.items():
        x = np.array([p.inputs.get(metric, np.nan) for p in ev.points])
        y = np.array([p.model.get(metric, np.nan) for p in ev.points])
        ok = np.isfinite(x) & np.isfinite(y)
        st = _style(label)
        ax.plot(x[ok], y[ok], "o", ms=4, color=st.get("color"), alpha=0.8, label=label)
        _band_bars(ax, x, y, ok, (bands or {}).get(label), ecolor=st.get("color"), elinewidth=0.8, capsize=2,
                   alpha=0.7, label=f"{label}: 95 % prediction band")
        if ok.any():
            lo, hi = min(lo, x[ok].min(), y[ok].min()), max(hi, x[ok].max(), y[ok].max())
    if np.isfinite(lo):
        pad = 0.05 * (hi - lo + 1e-9)
        xs = np.linspace(lo - pad, hi + pad, 50)
        m = METRICS[metric]
        tol = np.array([m.tol_for(v) for v in xs])
        ax.plot(xs, xs, "k-", lw=0.8)
        ax.fill_between(xs, xs - tol, xs + tol, color="tab:green", alpha=0.15, label="tolerance")
        ax.set_xlim(xs[0], xs[-1])
        ax.set_ylim(xs[0], xs[-1])
    ax.set_xlabel(f"data {_with_unit(metric)}")
    ax.set_ylabel(f"model {_with_unit(metric)}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{metric}: parity")
    return fig


def parity_panels(evals: Mapping[str, object], metric: str, bands: Mapping[str, np.ndarray] | None = None) -> Figure:
    """One parity panel per model state (e.g. baseline, after each step), same axes, with
    the tolerance band and the share within it in each title; more than
    :data:`PANELS_PER_ROW` panels wrap to rows. ``bands``: per label, the 95 % prediction
    band of each point (error bars)."""
    n = len(evals)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // PANELS_PER_ROW)
    fig = Figure(figsize=(2.6 * cols, 2.9 * rows), dpi=110)
    pairs = {}
    for label, ev in evals.items():
        x = np.array([p.inputs.get(metric, np.nan) for p in ev.points], float)
        y = np.array([p.model.get(metric, np.nan) for p in ev.points], float)
        pairs[label] = (x, y)
    allv = np.concatenate([np.concatenate(v) for v in pairs.values()]) if pairs else np.array([])
    allv = allv[np.isfinite(allv)]
    if not allv.size:
        return fig
    lo, hi = allv.min(), allv.max()
    pad = 0.08 * (hi - lo + 1e-9)
    xs = np.linspace(lo - pad, hi + pad, 50)
    m = METRICS[metric]
    tol = np.array([m.tol_for(v) for v in xs])
    for k, (label, (x, y)) in enumerate(pairs.items()):
        ax = fig.add_subplot(rows, cols, k + 1)
        ax.fill_between(xs, xs - tol, xs + tol, color="tab:green", alpha=0.15, label="tolerance")
        ax.plot(xs, xs, "k-", lw=0.7)
        ok = np.isfinite(x) & np.isfinite(y)
        inside = np.abs(y - x) <= np.array([m.tol_for(v) for v in x]) + 1e-9
        ax.plot(x[ok & inside], y[ok & inside], "o", ms=3.5, color="tab:blue", label="within tolerance")
        ax.plot(x[ok & ~inside], y[ok & ~inside], "o", ms=3.5, color="tab:red", label="outside tolerance")
        _band_bars(ax, x, y, ok, (bands or {}).get(label), ecolor="k", elinewidth=0.6, capsize=1.5, alpha=0.6,
                   label="95 % prediction band")
        if k == 0:
            ax.legend(fontsize=6, loc="upper left")
        share = 100.0 * np.sum(ok & inside) / max(1, len(x))
        ax.set_title(f"{label}: {share:.0f} % in", fontsize=8)
        ax.set_xlim(xs[0], xs[-1])
        ax.set_ylim(xs[0], xs[-1])
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if k % cols == 0:
            ax.set_ylabel(f"model {_with_unit(metric)}", fontsize=8)
        ax.set_xlabel(f"data {_with_unit(metric)}", fontsize=8)
    return fig


def residuals_vs(before, after, metric: str, regressor: str) -> Figure:
    """Residual (model - data) of one metric against one regressor of the model's trims,
    before (grey) and after (blue) closing the loop, with the tolerance band."""
    fig, ax = _ax(None, (4.8, 3.4))
    unit, f = REGRESSORS[regressor]
    tol = METRICS[metric].tol_for(1.0)
    for label, ev, st in (("before", before, dict(color="tab:gray", marker="o", ms=4, ls="none", alpha=0.7)),
                          ("after", after, dict(color="tab:blue", marker="o", ms=4, ls="none"))):
        pts = [p for p in ev.points if p.trimmed and p.trim is not None and np.isfinite(p.error.get(metric, np.nan))]
        x = [f(p.trim) for p in pts]
        y = [p.error[metric] for p in pts]
        ax.plot(x, y, label=label, **st)
    ax.axhspan(-tol, tol, color="tab:green", alpha=0.12, label="tolerance")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel(f"{regressor} [{unit}]")
    ax.set_ylabel(f"{metric} model - data [{METRICS[metric].unit}]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"Residual of {metric} against the model's {regressor} ({unit})", fontsize=9)
    return fig


def aero_polars(curves: Mapping[str, object], ax=None) -> Figure:
    """CL vs alpha and CL vs CD for each model (curves: label -> AeroCurves: alpha_deg, CL, CD)."""
    if ax is None:
        fig = Figure(figsize=(9.0, 4.0), dpi=110)
        a1, a2 = fig.add_subplot(121), fig.add_subplot(122)
    else:
        fig, (a1, a2) = ax[0].figure, ax
    for label, c in curves.items():
        st = _style(label)
        a1.plot(c.alpha_deg, c.CL, label=label, **st)
        a2.plot(c.CD, c.CL, label=label, **st)
    a1.set_xlabel("angle of attack [deg]")
    a1.set_ylabel("CL [-]")
    a2.set_xlabel("CD [-]")
    a2.set_ylabel("CL [-]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    a1.set_title("Lift curve (elevator neutral, clean)")
    a2.set_title("Drag polar")
    return fig


def propeller_curves(tables: Mapping[str, object], ax=None) -> Figure:
    """C_THRUST and C_POWER vs advance ratio for each set of tables (fixed pitch, or the
    middle blade angle of a constant-speed propeller)."""
    fig, ax = _ax(ax)
    for label, t in tables.items():
        ct, cp = t.CT, t.CP
        note = ""
        if t.beta75_deg is not None:
            k = len(t.beta75_deg) // 2
            ct, cp = ct[:, k], cp[:, k]
            note = f" ({t.beta75_deg[k]:g} deg)"
        st = _style(label)
        ax.plot(t.J, ct, label=f"C_T {label}{note}", color=st.get("color"), ls=st["ls"])
        ax.plot(t.J, cp, label=f"C_P {label}{note}", color=st.get("color"), ls=":" if st["ls"] == "-" else "-.")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("advance ratio J [-]")
    ax.set_ylabel("coefficient [-]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("Propeller tables")
    return fig


def save(fig: Figure, path) -> None:
    fig.tight_layout()
    fig.savefig(path)


# --------------------------------------------------------------------------- G1000 logs

_SEGMENT_COLOURS = {"cruise": "tab:green", "climb": "tab:orange"}
PLOT_PANELS = ("altitude", "airspeed", "vertical speed", "pitch", "rpm", "fuel flow")


def plot_log(log: G1000Log, segments: Sequence[Segment], *, model: pd.DataFrame | None = None,
             ax: Sequence[Any] | None = None) -> Any:
    """Plot a log against time with the segments shaded; return the matplotlib Figure.

    Six stacked panels sharing the time axis [min]: altitude (AltB and pressure altitude),
    airspeed (IAS, logged TAS, computed KTAS), vertical speed, pitch, E1 RPM and fuel flow.
    Cruise segments are shaded green, climbs orange, each labelled with its number. ``model``,
    a DataFrame with one row per segment and columns ``t_start_s``, ``rpm``, ``roc_fpm`` and
    ``pitch_deg`` (NaN where a value does not apply), is drawn as black markers over the
    segment it belongs to (matched on ``t_start_s``), on the RPM, vertical-speed and pitch panels.
    ``ax`` may give six Axes to draw into; otherwise a new Figure is made without pyplot (no
    display is needed; it renders with Agg on ``savefig``).
    """
    if ax is None:
        fig = Figure(figsize=(11, 13), layout="constrained")
        axes = list(fig.subplots(len(PLOT_PANELS), 1, sharex=True))
    else:
        axes = list(ax)
        if len(axes) != len(PLOT_PANELS):
            raise ValueError(f"plot_log needs {len(PLOT_PANELS)} axes, got {len(axes)}")
        fig = axes[0].figure

    d = log.data
    tm = d["time_s"].to_numpy(float) / 60.0

    def col(name: str) -> np.ndarray:
        return pd.to_numeric(d[name], errors="coerce").to_numpy(float) if name in d else \
            np.full(len(d), np.nan)

    hp = pressure_altitude_ft(col("AltB"), col("BaroA"))
    ktas = ktas_from_kcas(kcas_from_kias(col("IAS")), hp, col("OAT"))
    a_alt, a_spd, a_vs, a_pitch, a_rpm, a_ff = axes
    a_alt.plot(tm, col("AltB"), lw=0.8, label="AltB")
    a_alt.plot(tm, hp, lw=0.8, ls="--", label="pressure altitude")
    a_alt.set_ylabel("altitude [ft]")
    a_spd.plot(tm, col("IAS"), lw=0.8, label="IAS")
    if "TAS" in d:
        a_spd.plot(tm, col("TAS"), lw=0.8, label="TAS (logged)")
    a_spd.plot(tm, ktas, lw=0.8, ls="--", label="KTAS (computed)")
    a_spd.set_ylabel("airspeed [kt]")
    a_vs.plot(tm, col("VSpd"), lw=0.6, label="VSpd")
    a_vs.set_ylabel("vertical speed [ft/min]")
    a_pitch.plot(tm, col("Pitch"), lw=0.6, label="Pitch")
    a_pitch.set_ylabel("pitch [deg]")
    a_rpm.plot(tm, col("E1 RPM"), lw=0.8, label="E1 RPM")
    a_rpm.set_ylabel("engine speed [rpm]")
    a_ff.plot(tm, col("E1 FFlow"), lw=0.8, label="E1 FFlow")
    a_ff.set_ylabel("fuel flow [gal/h]")
    a_ff.set_xlabel("time since start of log [min]")

    shaded: set[str] = set()
    for k, s in enumerate(segments, start=1):
        colour = _SEGMENT_COLOURS.get(s.kind, "tab:grey")
        for a in axes:
            label = f"{s.kind} segment" if (a is a_alt and s.kind not in shaded) else None
            a.axvspan(s.t_start_s / 60.0, s.t_end_s / 60.0, color=colour, alpha=0.25, lw=0,
                      label=label)
        shaded.add(s.kind)
        a_alt.annotate(f"{s.kind[:2]}{k}", xy=((s.t_start_s + s.t_end_s) / 120.0, 1.0),
                       xycoords=("data", "axes fraction"), ha="center", va="bottom", fontsize=7)

    if model is not None and len(model):
        missing = [c for c in ("t_start_s", "rpm", "roc_fpm", "pitch_deg") if c not in model]
        if missing:
            raise ValueError("model DataFrame lacks column(s): " + ", ".join(missing))
        starts = np.array([s.t_start_s for s in segments], dtype=float)
        labelled = False
        for _, row in model.iterrows():
            t_start = float(row["t_start_s"])
            k = int(np.argmin(np.abs(starts - t_start))) if starts.size else -1
            if k >= 0 and abs(starts[k] - t_start) <= 1.0:
                t_a, t_b = segments[k].t_start_s / 60.0, segments[k].t_end_s / 60.0
            else:
                t_a = t_b = t_start / 60.0
            for a, name in ((a_rpm, "rpm"), (a_vs, "roc_fpm"), (a_pitch, "pitch_deg")):
                v = float(row[name])
                if not math.isfinite(v):
                    continue
                a.plot([t_a, t_b], [v, v], color="k", lw=1.5)
                a.plot([(t_a + t_b) / 2.0], [v], "kD", ms=5,
                       label="model" if not labelled and a is a_rpm else None)
            labelled = True

    for a in axes:
        a.grid(True, lw=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="upper right", fontsize=7)
    title = log.airframe.get("airframe_name", "G1000 log")
    fig.suptitle(f"{title}: {Path(log.path).name}", fontsize=10)
    return fig


DYNAMIC_LABELS = {"q_deg_s": "pitch rate [deg/s]", "p_deg_s": "roll rate [deg/s]", "r_deg_s": "yaw rate [deg/s]",
                  "kcas": "KCAS [kt]", "rpm": "engine speed [rpm]"}
OFF_AXIS = {"phugoid": "period", "engine_acceleration": "RPM response time (10-90 %)"}   # metrics not on the y axis


def dynamic_response(results: Mapping[str, object], ax=None, band: np.ndarray | None = None) -> Figure:
    """One dynamic test flown by several models (``results``: label -> ``dynamics.TestResult``):
    the channel its metric reads over maneuver time, with the flight-test value (a line for a
    rate the model should reach, the text for a period); ``band``: the 95 % band of the last
    model's response (same samples), shaded."""
    fig, ax = _ax(ax, (6.4, 3.6))
    first = next(iter(results.values()))
    test = first.test
    for label, r in results.items():
        if r.trajectory is not None:
            style = _style("baseline" if label == "before" else "calibrated" if label == "after" else label)
            ax.plot(r.trajectory.time_s, r.trajectory[test.channel], label=label, **style)
    last = list(results.values())[-1]
    if band is not None and last.trajectory is not None and band.shape == last.trajectory.time_s.shape \
            and np.all(np.isfinite(band)):
        y = last.trajectory[test.channel]
        ax.fill_between(last.trajectory.time_s, y - band, y + band, color=STYLES["calibrated"]["color"], alpha=0.2,
                        lw=0, label="95 % band")
    m = test.metrics[0]
    if test.kind not in OFF_AXIS:
        ax.axhline(m.measured, color="k", lw=1.0, ls="-.", label=f"flight test {m.measured:g} {m.unit}")
        tol = m.tol()
        if math.isfinite(tol):
            ax.axhspan(m.measured - tol, m.measured + tol, color="k", alpha=0.08, lw=0,
                       label=f"tolerance {m.tolerance_text()}")
    else:
        tol = f" +- {m.tol():g}" if math.isfinite(m.tol()) else ""
        ax.set_title(f"flight test: {OFF_AXIS[test.kind]} {m.measured:g}{tol} {m.unit}", fontsize=9)
    ax.set_xlabel("maneuver time [s]")
    ax.set_ylabel(DYNAMIC_LABELS.get(test.channel, test.channel))
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    fig.suptitle(f"{test.id} {test.title}", fontsize=9)
    return fig
