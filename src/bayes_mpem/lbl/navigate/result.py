"""The result of :func:`~.driver.navigate` and its files (``docs/navigate.md``, ``docs/cli.md``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import norm

from ...exceptions import InputError
from ...io.results import write_csv, write_json, writing
from ...mixture.densities import CLASSES
from ..survey.survey import beacons_table, classified_table
from .checks import model_checks
from .dive import Dive, dive_with_dead_reckoning
from .objective import State


def finite(v):
    """``float(v)``, or None where it is not finite (JSON has no NaN or infinity).

    Examples
    --------
    >>> finite(1.5), finite(float("nan"))
    (1.5, None)
    """
    v = float(v)
    return v if math.isfinite(v) else None


def estimate(value, sd, z, *, lo=-np.inf, bound=None) -> dict:
    """``{"estimate", "sd", "interval"}``, a Wald interval ``value +- z sd`` (clipped at ``lo``).

    A value at its lower bound gets the one-sided interval ``[bound, value + z1 sd]`` and
    ``"at_bound": true`` (``docs/navigate.md``).

    Parameters
    ----------
    z : float
        Normal quantile of the (two-sided) interval.
    lo : float, default -inf
        Lower end of the parameter's range.
    bound : float, optional
        The lower bound the estimator can reach (a floor); default ``lo``.

    Examples
    --------
    >>> estimate(10.0, 1.0, 2.0)
    {'estimate': 10.0, 'sd': 1.0, 'interval': [8.0, 12.0]}
    >>> [round(v, 4) for v in estimate(0.0, 1.0, 1.959964, lo=0.0)["interval"]]
    [0.0, 1.6449]
    """
    bound = lo if bound is None else bound
    if sd is None or not math.isfinite(float(sd)) or sd < 0:
        return {"estimate": finite(value), "sd": None, "interval": [None, None]}
    if math.isfinite(bound) and value <= bound + 1e-9 * max(1.0, abs(bound)):
        z1 = float(norm.ppf(2.0 * norm.cdf(z) - 1.0))
        return {"estimate": finite(value), "sd": finite(sd),
                "interval": [finite(bound), finite(value + z1 * sd)], "at_bound": True}
    return {"estimate": finite(value), "sd": finite(sd),
            "interval": [finite(max(value - z * sd, lo)), finite(value + z * sd)]}


def _num(v, spec: str) -> str:
    """``format(v, spec)``, or ``"n/a"`` for a missing value."""
    return "n/a" if v is None else format(v, spec)


def _at_bound(node, path=()):
    """Yield ``(path, record)`` of every estimate in ``node`` marked ``"at_bound"``."""
    if isinstance(node, dict):
        if node.get("at_bound") is True:
            yield path, node
        for k, v in node.items():
            if k != "sigma_dp" or not path:  # a beacon's sigma_DP is the shared one
                yield from _at_bound(v, (*path, str(k)))


def _bound_line(path, rec) -> str:
    lo = rec["interval"][0]
    if path == ("sigma_dp",):
        return f"sigma_DP at its floor {lo:g} m (one-sided interval)"
    if len(path) >= 3 and path[0] == "beacons":
        what = " ".join(("weight of" if p == "weights" else p) for p in path[2:])
        return f"beacon {path[1]}: {what} at its bound {lo:g} (one-sided interval)"
    return f"{' '.join(path)} at its bound {lo:g} (one-sided interval)"


def quality_lines(summary: dict) -> list:
    """Every quality flag of a ``summary.json``, one line each (what the console prints).

    Parameters
    ----------
    summary : dict
        :meth:`Navigation.summary`.

    Returns
    -------
    list of str
        Beacon flags and reasons, every estimate at a bound (wherever the summary
        marks one ``"at_bound"``), the observability flags, non-convergence, the
        information behind the intervals and the skipped beacons.

    Examples
    --------
    >>> for line in quality_lines({"beacons": {"1": {"flags": ["sigma_MP at its floor"]}},
    ...                            "converged": False, "information": "observed (Louis)"}):
    ...     print(line)
    beacon 1: sigma_MP at its floor
    the ECM did NOT converge: raise --max-iter or loosen --tol
    intervals from the observed (Louis) information
    """
    out = []
    for bid, b in (summary.get("beacons") or {}).items():
        out += [f"beacon {bid}: {f}" for f in b.get("flags") or ()]
        if b.get("reason"):
            out.append(f"beacon {bid}: {b['reason']}")
    out += [_bound_line(path, rec) for path, rec in _at_bound(summary)]
    for f in summary.get("observability") or ():
        if f.get("kind") == "track":
            out.append(f"navigation not corrected for t = {f['start']:.0f}-{f['end']:.0f} s "
                       f"({f['n_epochs']} epochs, position sd up to {f['max_sd']:.3g} m): "
                       f"{f['reason']}")
        else:
            out.append(f["reason"])
    if summary.get("converged") is False:
        out.append("the ECM did NOT converge: raise --max-iter or loosen --tol")
    if summary.get("information"):
        out.append(f"intervals from the {summary['information']} information")
    for bid, why in (summary.get("skipped") or {}).items():
        out.append(f"beacon {bid} skipped: {why}")
    out += [f"model check, {f}" for f in (summary.get("model_checks") or {}).get("flags", ())]
    return out


@dataclass(frozen=True)
class Navigation:
    """A navigated dive.

    Attributes
    ----------
    dive : Dive
        The input, grouped into epochs.
    state : State
        The estimate: track, heading bias, speed scale, plane heights, scales, weights.
    cov : numpy.ndarray
        ``(K, 2, 2)`` covariance of every epoch's position (Laplace).
    global_sd : dict
        Posterior sd of ``beta`` (rad), ``scale`` and of each estimated plane
        height (``"d0:<beacon>"``).
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities of every reply (or a baseline's weights).
    beacons : dict
        Per beacon: ``mp`` (a multipath class), ``d0_free``, ``path_choice``
        (a record of :class:`~bayes_mpem.lbl.em.path_choice.PathChoice` or None).
    skipped : dict
        Beacons without a reply, with the reason.
    flags : list of dict
        Where the navigation was not corrected (:func:`.observability.assess`).
    n_iter : int
    converged : bool
    loglik : float
    history : dict
    options : dict
    timings : dict
        Wall-clock seconds per stage (``timings.json`` only).
    global_cov : numpy.ndarray
        ``(G, G)`` joint covariance of the globals, in the order of
        :attr:`global_sd`'s keys (``beta``, ``scale``, then the plane heights).
    track_global_cov : numpy.ndarray
        ``(K, 2, G)`` covariance of every epoch's position with the globals
        (what a filter started at the last epoch needs, :mod:`bayes_mpem.lbl.navigate.online`).
    """

    dive: Dive = field(repr=False)
    state: State = field(repr=False)
    cov: np.ndarray = field(repr=False)
    global_sd: dict
    resp: np.ndarray = field(repr=False)
    beacons: dict
    skipped: dict
    flags: list
    n_iter: int
    converged: bool
    loglik: float
    history: dict = field(repr=False)
    options: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict, repr=False)
    global_cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    track_global_cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 0)),
                                         repr=False)

    @property
    def track(self) -> np.ndarray:
        """``(K, 2)`` the estimated horizontal positions."""
        return self.state.track

    @property
    def corrected(self) -> bool:
        """True when no stretch of the track was left uncorrected (see :attr:`flags`)."""
        return not any(f["kind"] == "track" for f in self.flags)

    @property
    def uncorrected(self) -> np.ndarray:
        """``(K,)`` bool: the epochs of the stretches flagged not corrected (:attr:`flags`)."""
        t = self.dive.times
        out = np.zeros(t.size, bool)
        for f in self.flags:
            if f["kind"] == "track":
                out |= (t >= f["start"]) & (t <= f["end"])
        return out

    def track_table(self) -> pd.DataFrame:
        """One row per epoch: ``time, x, y, depth, sd_x, sd_y, cov_xy, dr_x, dr_y, n_replies``.

        Returns
        -------
        pandas.DataFrame
        """
        d = self.dive
        return pd.DataFrame({
            "time": d.times, "x": self.track[:, 0], "y": self.track[:, 1], "depth": d.depth,
            "sd_x": np.sqrt(self.cov[:, 0, 0]), "sd_y": np.sqrt(self.cov[:, 1, 1]),
            "cov_xy": self.cov[:, 0, 1], "dr_x": d.dr[:, 0], "dr_y": d.dr[:, 1],
            "n_replies": np.bincount(d.epoch, minlength=d.n_epochs)})

    def classified(self) -> pd.DataFrame:
        """Every input row with ``p_dp``, ``p_mp``, ``p_ol``, ``label`` and ``reason``.

        Returns
        -------
        pandas.DataFrame
            Same rows and order as the input (labels ``dp``, ``mp``, ``ol``,
            ``no_reply``).
        """
        d = self.dive
        fitted = {bid: (d.rows[d.beacon == j], self.resp[d.beacon == j])
                  for j, bid in enumerate(d.beacon_ids) if bid not in self.skipped}
        return classified_table(d.survey, fitted, {})

    def _beacon_summary(self, j: int, bid: str, z: float) -> dict:
        d, st, info = self.dive, self.state, self.beacons[bid]
        mine = d.beacon == j
        n = int(mine.sum())
        resp = self.resp[mine]
        depth = float(d.beacon_xyz[j, 2])
        out = {"n": n, "n_no_reply": int(np.sum(d.survey.no_reply & (d.survey.beacon == bid))),
               "beacon_depth": depth}
        n_dp = float(self.resp[:, 0].sum())
        floor = float(self.options.get("sigma_floor", 0.0))
        # MacKay's sd of log sigma (the residual degrees of freedom), else sqrt(2 n)'s
        sd_log = (self.options.get("scale_uncertainty") or {}).get("sd_log_sigma", {})
        if self.options.get("sigma_dp") is not None:
            out["sigma_dp"] = {"estimate": finite(st.sigma_dp), "sd": None,
                               "interval": [None, None], "fixed": True}
        else:
            rel = sd_log.get("sigma_dp", 1.0 / math.sqrt(2 * max(n_dp, 1)))
            out["sigma_dp"] = estimate(st.sigma_dp, st.sigma_dp * rel, z, lo=0.0, bound=floor)
        if info["mp"]:
            n_mp = float(resp[:, 1].sum())
            sd0 = self.global_sd.get(f"d0:{bid}", 0.0)
            out["d0"] = estimate(st.d0[j], sd0, z, lo=float(d.d0_min[j]))
            out["plane_depth"] = depth - float(st.d0[j])
            rel = sd_log.get(f"sigma_mp:{bid}", 1.0 / math.sqrt(2 * max(n_mp, 1)))
            out["sigma_mp"] = estimate(st.sigma_mp[j], st.sigma_mp[j] * rel, z, lo=0.0,
                                       bound=floor)
            out["path"] = "double" if st.double[j] else "triangle"
        else:
            out["d0"] = out["sigma_mp"] = out["path"] = out["plane_depth"] = None
            out["reason"] = info.get("reason", "multipath treated as outliers")
        w = st.weights[j]
        out["weights"] = {c: estimate(w[i], math.sqrt(w[i] * (1 - w[i]) / max(n, 1)), z, lo=0.0)
                          for i, c in enumerate(CLASSES)}
        if not info["mp"]:  # no multipath class: its weight is 0 by the model, not estimated
            out["weights"]["mp"] = {"estimate": 0.0, "sd": None, "interval": [None, None],
                                    "fixed": True}
        lab = np.argmax(resp, axis=1) if n else np.zeros(0, int)
        out["class_fractions"] = {c: finite(np.mean(lab == i)) if n else None
                                  for i, c in enumerate(CLASSES)}
        out["path_choice"] = info.get("path_choice")
        out["flags"] = list(info.get("flags", ()))
        return out

    def summary(self) -> dict:
        """Return the content of ``summary.json`` (no wall-clock time: same input, same bytes).

        Returns
        -------
        dict
        """
        ci = float(self.options.get("ci", 0.95))
        z = float(norm.ppf(0.5 + ci / 2))
        d, st = self.dive, self.state
        beacons = {bid: self._beacon_summary(j, bid, z) for j, bid in enumerate(d.beacon_ids)
                   if bid not in self.skipped}
        sd = np.sqrt(self.cov[:, [0, 1], [0, 1]])
        dr = {"heading_bias_deg": estimate(np.rad2deg(st.beta),
                                           np.rad2deg(self.global_sd["beta"]), z),
              "speed_scale": estimate(st.scale, self.global_sd["scale"], z, lo=0.0),
              "dr_noise": self.options.get("dr_noise"), "source": d.dr_source}
        rs = (estimate(st.range_scale, self.global_sd["range_scale"], z, lo=0.0)
              if "range_scale" in self.global_sd else None)
        return {
            "model": self.options.get("model"), "multipath": self.options.get("multipath"),
            "range_scale": rs, "model_checks": model_checks(self),
            "beacons": beacons, "sigma_dp": beacons[next(iter(beacons))]["sigma_dp"]
            if beacons else None,
            "dead_reckoning": dr,
            "track": {"n_epochs": d.n_epochs, "sd_median": finite(np.median(sd.max(axis=1))),
                      "sd_max": finite(sd.max())},
            "navigation_corrected": self.corrected, "observability": list(self.flags),
            "iterations": self.n_iter, "converged": self.converged, "loglik": finite(self.loglik),
            "beacons_table": beacons_table(d.survey), "skipped": dict(self.skipped),
            "n_rows": len(d.survey), "n_replies": d.n,
            "n_no_reply": int(d.survey.no_reply.sum()), "ci": ci,
            "pings": d.survey.pings_source, "beacons_file": d.survey.beacons_source,
            "information": self.options.get("information"),
            "scale_uncertainty": self.options.get("scale_uncertainty"),
            "options": {k: v for k, v in self.options.items()
                        if k not in ("rng", "ci", "information", "scale_uncertainty")},
        }

    def to_dict(self) -> dict:
        """Return the content of ``summary.json`` (the same as :meth:`summary`).

        Returns
        -------
        dict
        """
        return self.summary()

    def format_table(self) -> str:
        """Per-beacon reflectors and the dead-reckoning nuisances, as aligned text.

        Returns
        -------
        str
        """
        s = self.summary()
        lines = [f"{'beacon':>6} {'d0 (m)':>9} {'+-':>5} {'sigma_MP':>8} {'path':>8} "
                 f"{'DP':>6} {'MP':>6} {'OL':>6} {'n':>6}"]
        for bid, b in s["beacons"].items():
            cf = b["class_fractions"]
            if b["d0"] is None:
                left = f"{'-':>9} {'':>5} {'-':>8} {'-':>8}"
            else:
                lo_, hi_ = b["d0"]["interval"]
                half = (None if lo_ is None or hi_ is None or b["d0"].get("at_bound")
                        else (hi_ - lo_) / 2)
                left = (f"{b['d0']['estimate']:9.1f} {_num(half, '5.1f'):>5} "
                        f"{_num(b['sigma_mp']['estimate'], '8.2f'):>8} {b['path']:>8}")
            lines.append(f"{bid:>6} {left} {cf['dp'] or 0:6.3f} {cf['mp'] or 0:6.3f} "
                         f"{cf['ol'] or 0:6.3f} {b['n']:6d}")
        dr = s["dead_reckoning"]
        hb, sc, tr = dr["heading_bias_deg"], dr["speed_scale"], s["track"]
        lines.append(f"heading bias {_num(hb['estimate'], '.3f')} deg "
                     f"(sd {_num(hb['sd'], '.3f')}), speed scale "
                     f"{_num(sc['estimate'], '.4f')} (sd {_num(sc['sd'], '.4f')}); "
                     f"track sd median {_num(tr['sd_median'], '.2f')} m, "
                     f"max {_num(tr['sd_max'], '.3g')} m")
        rs = s.get("range_scale")
        if rs:
            lines.append(f"range scale {_num(rs['estimate'], '.6f')} "
                         f"(sd {_num(rs['sd'], '.6f')})")
        sdp = s.get("sigma_dp")
        if sdp:
            kind = ("given" if sdp.get("fixed") else
                    f"sd {_num(sdp['sd'], '.3g')}, {s['ci']:.0%} interval "
                    f"[{_num(sdp['interval'][0], '.3g')}, {_num(sdp['interval'][1], '.3g')}]")
            lines.append(f"sigma_DP {_num(sdp['estimate'], '.3g')} m ({kind})")
        notes = quality_lines(s)
        if notes:
            lines.append("quality flags (summary.json):")
            lines += [f"  - {n}" for n in notes]
        return "\n".join(lines)

    def write(self, out_dir) -> dict:
        """Write ``track.csv``, ``classified.csv``, ``summary.json`` and ``timings.json``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            Paths written, keyed ``track``, ``classified``, ``summary``, ``timings``.
        """
        with writing(out_dir) as out:
            return {"track": write_csv(out / "track.csv", self.track_table()),
                    "classified": write_csv(out / "classified.csv", self.classified()),
                    "timings": write_json(out / "timings.json", dict(self.timings)),
                    "summary": write_json(out / "summary.json", self.summary())}

    @classmethod
    def read(cls, folder) -> Navigation:
        """Read a navigation back from the folder :meth:`write` wrote, never by fitting again.

        No history, timings, joint covariances or per-beacon model records: it draws but
        does not write.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        Navigation

        Raises
        ------
        FileNotFoundError
            A missing file.
        InputError
            A track that does not fit the pings.
        """
        from pathlib import Path

        from ...io.results import MARKER, read_document
        from ...io.table_files import read_table_file
        from ..survey.folder import survey_and_classes, together

        d = Path(folder)
        summary = read_document(d / MARKER)
        path = d / "track.csv"
        if not path.exists():
            raise FileNotFoundError(f"{path}: not found; 'bayes-mpem navigate' writes it")
        text = read_table_file(path, str(path), "track file")
        survey, probs, _ = survey_and_classes(d, summary)
        return together(d, _from_tables, cls, summary, survey, text.frame, probs, path,
                        text.lines)


def _value(entry) -> float:
    """Return the estimate of a ``summary.json`` entry (a number or ``{"estimate": ...}``)."""
    v = entry.get("estimate") if isinstance(entry, dict) else entry
    return np.nan if v is None else float(v)


def _from_tables(cls, summary: dict, survey, track: pd.DataFrame, probs: np.ndarray,
                 path="track.csv", lines=None):
    """Rebuild a :class:`Navigation` from its files' content (:meth:`Navigation.read`).

    ``lines``: the file line of each row of ``track`` (named in errors), else its row.
    """
    missing = [c for c in ("time", "x", "y", "sd_x", "sd_y", "cov_xy", "dr_x", "dr_y")
               if c not in track.columns]
    if missing:
        raise InputError(f"{path}: no column(s) {missing}; expected the track of "
                         "'bayes-mpem navigate'")

    def where(i):
        return f"{path} " + (f"line {int(lines[i])}" if lines is not None else f"row {i + 1}")

    col = {}
    for c in ("time", "x", "y", "sd_x", "sd_y", "cov_xy", "dr_x", "dr_y"):
        text = track[c].astype(str).str.strip()
        col[c] = pd.to_numeric(text.replace({"": "nan"}), errors="coerce").to_numpy(float)
        empty = ~np.isfinite(col[c]) if c == "time" else np.zeros(len(text), bool)
        bad = np.flatnonzero(np.isnan(col[c]) & ~text.str.lower().isin(["", "nan"]).to_numpy()
                             | empty)
        if bad.size:
            raise InputError(f"{where(int(bad[0]))}, column {c!r}: expected a "
                             f"{'finite ' if c == 'time' else ''}number, got "
                             f"{track[c].iloc[bad[0]]!r}")
    try:
        dive = dive_with_dead_reckoning(
            survey, col["time"], np.column_stack([col["dr_x"], col["dr_y"]]),
            str((summary.get("dead_reckoning") or {}).get("source") or "pings"))
    except InputError as exc:
        raise InputError(f"{path}: its times are not those of the classified table's pings "
                         f"(was one edited?): {exc}") from None
    cov = np.empty((dive.n_epochs, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = col["sd_x"] ** 2, col["sd_y"] ** 2
    cov[:, 0, 1] = cov[:, 1, 0] = col["cov_xy"]
    beacons = [summary["beacons"].get(b, {}) for b in dive.beacon_ids]
    dr = summary.get("dead_reckoning") or {}
    state = State(
        track=np.column_stack([col["x"], col["y"]]),
        beta=np.deg2rad(_value(dr.get("heading_bias_deg"))),
        scale=_value(dr.get("speed_scale")),
        d0=np.array([_value(b.get("d0")) for b in beacons]),
        double=np.array([b.get("path") == "double" for b in beacons]),
        sigma_dp=_value(summary.get("sigma_dp")),
        sigma_mp=np.array([_value(b.get("sigma_mp")) for b in beacons]),
        weights=np.array([[_value((b.get("weights") or {}).get(c)) for c in CLASSES]
                          for b in beacons]).reshape(len(beacons), 3),
        range_scale=1.0 if summary.get("range_scale") is None
        else _value(summary["range_scale"]))
    return cls(dive=dive, state=state, cov=cov, global_sd={},
               resp=np.asarray(probs, float)[dive.rows], beacons={},
               skipped=dict(summary["skipped"]), flags=list(summary.get("observability") or []),
               n_iter=summary.get("iterations", 0), converged=summary.get("converged"),
               loglik=summary.get("loglik"), history={}, options=summary.get("options", {}))
