"""What locating the transponders of a survey returns, and the files it writes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..io.results import write_csv, write_file, write_json, writing

#: Columns of ``classified.csv`` after the first seven, per ping: the ship's
#: transducer (``east``, ``north``, m in the survey's frame) and the moment
#: (``time``, s), the residual (observed minus predicted two-way travel time of a
#: true reply, ms) and the azimuth of the ship seen from the transponder (degrees
#: clockwise from north).
PING_COLUMNS = ("time", "east", "north", "residual_ms", "azimuth_deg")


def classified_table(pings: pd.DataFrame, p_true, skipped: pd.DataFrame, *, reasons=None,
                     extra=()) -> pd.DataFrame:
    """Build ``classified.csv``: one row per ping and per skipped line, in file order.

    Parameters
    ----------
    pings : pandas.DataFrame
        ``line``, ``transponder``, ``twtt`` and the :data:`PING_COLUMNS` (and
        ``file`` when a survey spans several files).
    p_true : array_like
        Probability of a true reply per ping; NaN for a ping left out (its
        reason in ``reasons``).
    skipped : pandas.DataFrame
        ``line``, ``reason`` (and ``file``) of the lines that are not pings.
    reasons : array_like of str, optional
        Per ping, why it was left out ("" when it was not).
    extra : sequence of str
        Further columns of ``pings`` to keep (e.g. ``file_flag``).

    Returns
    -------
    pandas.DataFrame
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``), ``reason``, then
        :data:`PING_COLUMNS` and ``extra`` (``file`` second when present).

    Examples
    --------
    >>> import pandas as pd
    >>> pings = pd.DataFrame({"line": [2, 3], "transponder": "A", "twtt": [1.0, 9.0],
    ...                       "time": [0.0, 5.0], "east": 0.0, "north": 0.0,
    ...                       "residual_ms": [0.1, 8000.0], "azimuth_deg": 0.0})
    >>> skipped = pd.DataFrame({"line": [1], "reason": ["no reply"]})
    >>> classified_table(pings, [0.99, 0.0], skipped)["label"].tolist()
    ['skipped', 'true', 'spurious']
    """
    p = np.asarray(p_true, float)
    left = np.isnan(p)
    lab = np.where(left, "skipped", np.where(p >= 0.5, "true", "spurious")).astype(object)
    why = np.full(len(pings), "", dtype=object) if reasons is None else np.asarray(reasons,
                                                                                  object)
    cls = pd.DataFrame({"line": pings["line"].to_numpy(),
                        "transponder": pings["transponder"].astype(str).to_numpy(),
                        "twtt": pings["twtt"].to_numpy(float), "p_true": p,
                        "p_spurious": 1.0 - p, "label": lab, "reason": why})
    for c in (*PING_COLUMNS, *extra, *(["file"] if "file" in pings.columns else [])):
        cls[c] = pings[c].to_numpy()
    if len(skipped):
        sk = pd.DataFrame({"line": skipped["line"].to_numpy(), "transponder": "",
                           "twtt": np.nan, "p_true": np.nan, "p_spurious": np.nan,
                           "label": "skipped", "reason": skipped["reason"].to_numpy()})
        if "file" in skipped.columns:
            sk["file"] = skipped["file"].to_numpy()
        cls = pd.concat([cls, sk], ignore_index=True)
    keys = ["line"]
    if "file" in cls.columns:
        cls.insert(1, "file", cls.pop("file"))
        keys = ["file", "line"]
    return cls.sort_values(keys, kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class SurveyInResult:
    """Every transponder of a survey, located.

    Attributes
    ----------
    summary : dict
        ``{"transponders": {id: {"lat", "lon", "depth", "sound_speed", ...}}, ...}``
        (the content of ``summary.json``).
    classified : pandas.DataFrame
        One row per ping line and per skipped line of the file, in file order:
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``) and ``reason``.
    posteriors : dict
        ``{id: LocationPosterior}`` when the posterior was sampled, else empty.
    fits : dict
        ``{id: LocateResult}``, the EM fit of each transponder (not written).

    Examples
    --------
    >>> import pandas as pd
    >>> res = SurveyInResult({"transponders": {}}, pd.DataFrame({"line": [1]}))
    >>> res.to_dict()
    {'transponders': {}}
    """

    summary: dict
    classified: pd.DataFrame
    posteriors: dict = field(default_factory=dict, repr=False)
    fits: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """Return the content of ``summary.json``."""
        return self.summary

    def write(self, out_dir) -> dict:
        """Write ``summary.json`` and ``classified.csv`` (and an array's ``solution.txt``).

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            Paths written, keyed ``summary`` and ``classified`` (and ``solution``
            for an array, the solution as plain text; ``posterior_<id>`` for each sampled
            posterior: :func:`~.posterior.write_posterior`).
        """
        from .posterior import posterior_file, write_posterior

        with writing(out_dir) as out:
            paths = {"classified": write_csv(out / "classified.csv", self.classified)}
            for name, post in self.posteriors.items():
                paths[posterior_file(name)[:-3]] = write_file(
                    out / posterior_file(name),
                    lambda tmp, post=post: write_posterior(tmp, post.to_inference_data()))
            if "array_centre" in self.summary:
                text = _solution_text(self.summary)
                paths["solution"] = write_file(out / "solution.txt",
                                               lambda tmp: tmp.write_text(text))
            paths["summary"] = write_json(out / "summary.json", self.summary)
            return paths

    @classmethod
    def read(cls, folder) -> SurveyInResult:
        """Read a located survey back from the folder :meth:`write` wrote (no fits or posteriors).

        A missing ``classified.csv`` is a ``FileNotFoundError``; one of an older version, or
        whose rows are not the summary's pings and skipped lines, an ``InputError``.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        SurveyInResult
        """
        from pathlib import Path

        from ..exceptions import InputError
        from ..io.results import MARKER, read_document

        summary = read_document(Path(folder) / MARKER)
        path = Path(folder) / "classified.csv"
        if not path.exists():
            raise FileNotFoundError(f"{path}: not found; 'bayes-mpem locate' writes it")
        cls_ = pd.read_csv(path, keep_default_na=False, na_values=[""],
                           dtype={"transponder": str, "label": str, "reason": str})
        cls_["transponder"] = cls_["transponder"].fillna("")
        missing = [c for c in ("residual_ms", "azimuth_deg", "east", "north", "time")
                   if c not in cls_.columns]
        if missing:
            raise InputError(f"{path}: no column(s) {missing}; it was written by an older "
                             "bayes_mpem: run 'bayes-mpem locate' again")
        if "n_pings" in summary:  # one row per ping and per skipped line
            expected = int(summary["n_pings"]) + int(summary.get("n_skipped_lines", 0))
            if len(cls_) != expected:
                raise InputError(f"{path}: {len(cls_)} rows; expected {expected}, the "
                                 f"{summary['n_pings']} pings and "
                                 f"{summary.get('n_skipped_lines', 0)} skipped lines of "
                                 f"{Path(folder) / MARKER}: the file is cut short or from "
                                 "another run; run 'bayes-mpem locate' again")
        return cls(summary=summary, classified=cls_)


def _row(name, enu, width=14):
    vals = [enu[c]["mean"] for c in ("east", "north", "up")]
    sds = [enu[c]["sd"] for c in ("east", "north", "up")]
    return (f"{name:<{width}}" + "".join(f"{v:14.3f}" for v in vals)
            + "".join(f"{v:9.3f}" for v in sds))


def centre_note(summary: dict) -> str | None:
    """Return what the array centre averages when a transponder was not located, else None.

    The centre is the mean of the located transponders: with one left out it is another
    point of the seafloor, and a campaign's centre is then not comparable with that of a
    campaign that located them all.

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (``array_centre``, ``skipped_transponders``).

    Returns
    -------
    str or None
        ``"the mean of M01, M02, M03 only (M04 not located): ..."``; None where every
        transponder was located.
    """
    skipped = list(summary.get("skipped_transponders", {}))
    if not skipped:
        return None
    used = summary["array_centre"].get("transponders") or list(summary["transponders"])
    note = (f"the mean of {', '.join(map(str, used))} only ({', '.join(map(str, skipped))} "
            f"not located): not comparable with a centre of all "
            f"{len(used) + len(skipped)} transponders")
    whole = (summary.get("positions") or {}).get("centre_of_all")
    if whole:
        note += ("; the prior geometry moved by the shift puts that centre at east "
                 + ", north ".join(f"{whole[c]['mean']:.3f}" for c in ("east", "north"))
                 + f", up {whole['up']['mean']:.3f} m (sds those of the shift)")
    return note


#: The prior check's p-value below which :func:`positions_line` says the site file's sigmas
#: look too small (``positions.prior.check``).
PRIOR_CONFLICT_P = 0.01


def positions_line(summary: dict) -> str | None:
    """Return how the positions were constrained by the site file's sigmas, else None.

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (``positions``).

    Returns
    -------
    str or None
        The rigid shift of the prior geometry with its sds (GARPOS's ``dCentPos`` of a
        fixed-geometry solution; a coordinate held by a sigma of 0 said so), or how many
        coordinates a sigma of 0 held; then the priors of the sigmas above 0, naming the
        coordinates the prior mostly determines. None where every coordinate was solved
        freely.
    """
    pos = summary.get("positions") or {}
    parts = []
    if "shift" in pos:
        d = pos["shift"]
        parts.append("rigid shift of the prior geometry (fixed geometry): "
                     + ", ".join(f"{c} {d[c]['mean']:+.3f} +- {d[c]['sd']:.3f}" if d[c]["sd"] > 0
                                 else f"{c} held (sigma 0)" for c in ("east", "north", "up"))
                     + " m")
    elif pos.get("n_moved_by_shift_only") is not None:
        moved = pos["n_moved_by_shift_only"]
        parts.append("each transponder's offset and a common shift of the array solved "
                     "(GARPOS's dPos and dCentPos)"
                     + (f": {moved} coordinate{'s' * (moved != 1)} whose sigma is 0 moved by "
                        "the shift only (GARPOS's array take-over)" if moved else "")
                     + (f"; {pos['n_fixed']} held at "
                        + ("its prior position" if pos["n_fixed"] == 1 else
                           "their prior positions") if pos.get("n_fixed") else ""))
        d = pos.get("common_shift") or {}
        if d:
            parts.append("the common shift (dCentPos): " + ", ".join(
                f"{c} {v['mean']:+.3f} +- {v['sd']:.3f}" for c, v in d.items()) + " m")
    elif pos.get("n_fixed"):
        total = pos.get("n_coordinates", pos["n_fixed"] + pos["n_free"])
        parts.append(f"{pos['n_fixed']} of {total} coordinates held at their prior positions "
                     "(sigma 0)")
    prior = pos.get("prior")
    if prior:
        if "shift_sd" in prior:
            sds = [v for v in prior["shift_sd"] if v]
        else:
            sds = [v for row in prior["transponder_sd"].values() for v in row if v]
            sds += [v for v in prior["centre_sd"] if v]
        lo, hi = min(sds), max(sds)
        span = f"{lo:.3g} m" if lo == hi else f"{lo:.3g}-{hi:.3g} m"
        scaled = prior.get("scaled")
        n = prior["n_with_prior"]
        on = f"on {n} parameter{'s' * (n != 1)}"
        first = (scaled or {}).get("check_as_given") or {}
        text = (f"Gaussian priors from the site file's sigmas {on} (sd {span})" if not scaled
                else f"Gaussian priors from the site file's sigmas scaled up "
                f"{scaled['sd_factor']:.2f} times {on} (sd {span}): the fit moved the positions "
                f"farther from the site file's than its sigmas allow (chi-squared "
                f"{first['chi2']:.1f} on {first['dof']}, p {first['p_value']:.2g}; "
                "--position-prior site keeps them)")
        spread = (scaled or {}).get("scale_uncertainty")
        if spread:
            lo_k, hi_k = spread["kappa_interval"]
            text += (f"; the intervals carry the scale's uncertainty (variance factor "
                     f"{lo_k:.3g}-{hi_k:.3g}, 95 %)")
        most = prior.get("mostly_prior") or []
        text += ("; the prior, not the shots, gives most of the precision of "
                 + ", ".join(most) if most else "; the shots dominate every one")
        check = prior.get("check")
        if check and check["p_value"] < PRIOR_CONFLICT_P:
            text += (f"; CAUTION: the fit moved the positions farther from the site file's than "
                     f"its sigmas allow (chi-squared {check['chi2']:.1f} on {check['dof']}, p "
                     f"{check['p_value']:.1g}): the sigmas look too small, and the intervals "
                     "lean on them (--position-prior off, or larger sigmas)")
        parts.append(text)
    return "; ".join(parts) if parts else None


def gradients_line(summary: dict) -> str:
    """Return one line: the array's horizontal gradients, fitted or not and why.

    Where fitted, their time averages, and what the evidence over their smoothing weight
    says when it is largest at an end of its grid or flat (``gradient_grid["edge"]``).

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (with ``gradients``).

    Returns
    -------
    str
    """
    g = summary.get("gradients") or {}
    line = f"gradients     {'fitted' if g.get('fitted') else 'not fitted'} ({g.get('reason', '-')})"
    if g.get("fitted") and "shallow_east" in g:
        line += "; time averages (m/s)/km: " + ", ".join(
            f"{k.replace('_', ' ')} {g[k]['mean']:+.4f} +- {g[k]['sd']:.4f}"
            for k in ("shallow_east", "shallow_north", "deep_east", "deep_north") if k in g)
    grid = ((summary.get("sound_speed") or {}).get("smoothing") or {}).get("gradient_grid") or {}
    note = _edge_note(grid.get("edge"), "the gradients", "their")
    return line + (f"; {note}" if note else "")


def _edge_note(edge, what: str, whose: str, rough_hint: str = "") -> str:
    """Say what a smoothing grid's ``edge`` (``summary.json``) means for ``what``, or ''."""
    return {"stiff": "the evidence is largest at the stiffest smoothing tried: the data ask for "
                     f"no change of {what} beyond a linear trend",
            "rough": "the evidence is largest at the roughest smoothing tried" + rough_hint,
            "flat": f"{whose} smoothing weight is not determined by the data: the evidence "
                    "within 1 nat over 4 decades, and the intervals average over it"
            }.get(edge, "")


def _speed_grid_note(sound_speed: dict) -> str:
    """Say what the evidence over the speed's smoothing weight says at its grid's end, or ''."""
    grid = (sound_speed.get("smoothing") or {}).get("grid") or {}
    note = _edge_note(grid.get("edge"), "the speed", "its", ": the speed may change faster "
                      "than these knots follow; try a shorter --knot-minutes")
    return f" ({note})" if note else ""


def not_fitted_note(summary: dict) -> str | None:
    """Return how many shots read were not fitted and why, else None.

    A shot flagged in the file (honoured), isolated in time
    (:func:`~.array_survey.isolated_shots`) or of a transponder not located is read but not
    fitted: it is in ``n_pings`` and in ``classified.csv`` (label ``skipped``, with the
    reason), neither true nor spurious.

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (``n_pings``, ``residuals``, ``not_fitted``: a shot of
        a transponder not located counts there even when flagged, as in ``classified.csv``).

    Returns
    -------
    str or None
        ``"14 shots not fitted: 10 flagged in the file, 4 of a transponder not located
        (reasons in classified.csv)"``; None where every shot read was fitted.
    """
    r = summary.get("residuals") or {}
    if "n_true" not in r:
        return None
    n = int(summary["n_pings"]) - r["n_true"] - r["n_spurious"]
    if n <= 0:
        return None
    left = summary.get("not_fitted") or {}
    flagged = left.get("flagged", 0)  # as classified.csv has it
    isolated = left.get("isolated_in_time", 0)
    parts = [f"{flagged} flagged in the file"] if flagged else []
    if isolated:
        parts.append(f"{isolated} isolated in time")
    if n - flagged - isolated:
        parts.append(f"{n - flagged - isolated} of a transponder not located")
    return (f"{n} shot{'s' * (n != 1)} not fitted: {', '.join(parts)} (reasons in "
            "classified.csv)")


def circle_note(summary: dict) -> str | None:
    """Return a caution where the deep gradient was fitted on a track hardly over the array.

    On a circle about the array (``gradients.deep_gate``: too few shots within
    ``CENTRAL_RADIUS`` depths of its centre) the deep gradient trades with the centre's
    horizontal position: on the simulator's 6-hour circles the centre's horizontal sds were
    1.1 m with both terms and 0.6-1.6 cm with the shallow one only (docs/gnssa.md, "Circles:
    the shallow gradient only"). ``auto`` fits the shallow one only there (none on a circle
    shorter than 3 h); this is said where ``--gradients on`` forced both. Summaries without
    ``deep_gate`` (before 2026-11-29) are judged by ``track.central_fraction`` 0.

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (``gradients``, ``track``, ``array_centre``).

    Returns
    -------
    str or None
    """
    g, track = summary.get("gradients") or {}, summary.get("track") or {}
    gate = g.get("deep_gate")
    hardly = (not gate["fit"]) if gate else track.get("central_fraction", 1.0) == 0.0
    if "deep_east" not in g or not hardly:
        return None
    c = summary["array_centre"]["enu"]
    return (f"the deep gradient was fitted on a track hardly over the array: it trades with "
            f"the centre's horizontal position (sds east {c['east']['sd']:.3f}, north "
            f"{c['north']['sd']:.3f} m); --gradients shallow (auto's choice for this track) "
            "determines it to cm")


def centre_notes(summary: dict) -> list[str]:
    """Return the lines said under an array's centre: what it averages, and its cautions.

    :func:`centre_note`, :func:`short_note` and :func:`circle_note`, those that apply, in
    that order (the terminal and ``solution.txt`` print the same).

    Parameters
    ----------
    summary : dict
        An array's ``summary.json``.

    Returns
    -------
    list of str
    """
    return [n for n in (centre_note(summary), short_note(summary), circle_note(summary)) if n]


#: Campaigns shorter than this (hours) get :func:`short_note`.
SHORT_HOURS = 1.0


def short_note(summary: dict) -> str | None:
    """Return a caution for an array campaign shorter than :data:`SHORT_HOURS`, else None.

    On simulated campaigns of 30 minutes (circles, stars, a ship holding station;
    ``benchmarks/gnssa_short.py``) the centre's horizontal 95 % intervals covered 80-87 % of
    the truths; from an hour, 87-100 % on every track. On an independently written
    generator's half-hour star (one straight pass) they covered 60 % without the site file's
    priors on the positions and 97 % with them (:func:`positions_line`).

    Parameters
    ----------
    summary : dict
        An array's ``summary.json`` (``epoch.hours``).

    Returns
    -------
    str or None
    """
    hours = (summary.get("epoch") or {}).get("hours")  # first to last shot: an hour of
    if hours is None or hours >= 0.95 * SHORT_HOURS:  # shots spans a little less
        return None
    return (f"the shots span {hours:.2f} h: on simulated 30-minute campaigns the centre's "
            "horizontal 95 % intervals covered only 80-87 % of the truths (one straight pass: "
            "60 % without the site file's priors on the positions, 97 % with them; "
            "docs/gnssa.md, \"Short campaigns\"); read them as too narrow")


def noise_line(summary: dict) -> str:
    """Return one line: the replies' noise model (``summary.json`` ``noise``).

    Parameters
    ----------
    summary : dict
        An array's ``summary.json``.

    Returns
    -------
    str
    """
    nz = summary.get("noise") or {}
    tau = nz.get("correlation_s") or 0.0
    how = nz.get("choice", "-")
    if tau <= 0:
        line = f"noise         independent replies ({how})"
    else:
        line = (f"noise         correlated: mu_t {tau:g} s, mu_mt {nz['share']:g}, white "
                f"{nz.get('white') or 0:g} ({how}; generalised least squares)")
    if nz.get("at_grid_edge"):
        line += "; at the edge of the choices tried"
    return line


def _solution_text(summary: dict) -> str:
    """Return an array's solution as plain text, for a log (``solution.txt``)."""
    s = summary
    ep = s.get("epoch") or {}
    geo = s.get("geometry", {})
    org = geo.get("origin")
    where = ("local east, north, up (m) about lat {lat:.8f}, lon {lon:.8f}, height {height:.3f} m"
             .format(**org) if org else "the survey's local east, north, up (m)")
    utc = f", UTC {ep['utc']}" if ep.get("utc") else ""
    lines = ["bayes_mpem GNSS-A array solution",
             f"site          {s.get('site') or '-'}",
             f"campaign      {s.get('campaign') or '-'}",
             f"source        {s.get('source', '-')} ({s.get('format', '-')})"]
    if ep:
        lines.append(f"epoch         t_tx {ep['t_tx_mid']:.1f} (mid-survey; "
                     f"{ep['time_reference']}){utc}; {ep['hours']:.2f} h of shots")
    lines += [f"frame         {where}", "",
              f"{'':<14}{'east':>14}{'north':>14}{'up':>14}{'sd_e':>9}{'sd_n':>9}{'sd_u':>9}",
              _row("array centre", s["array_centre"]["enu"])]
    for tid, t in s["transponders"].items():
        lines.append(_row(str(tid), t["enu"]))
    for tid, why in s.get("skipped_transponders", {}).items():
        lines.append(f"{tid:<14}not located: {why}")
    lines += [f"{'':<14}array centre: {note}" for note in centre_notes(s)]
    pos = positions_line(s)
    if pos:
        lines.append(f"positions     {pos}")
    ss = s["sound_speed"]
    lines += ["", f"sound speed   {ss['mean']:.3f} +- {ss['sd']:.3f} {ss['unit']} "
                  f"({ss.get('quantity', '')})",
              f"speed model   {ss.get('model', '-')}"
              # the smooth spline's model names its knot spacing already
              + (f", {ss['interval_minutes']:.1f} min each"
                 if ss.get("interval_minutes") and not ss.get("smoothing") else "")
              + _speed_grid_note(ss) + f"; {s.get('method', '')}"]
    r = s.get("residuals")
    if r:
        per = ", ".join(f"{k} {v['rms_true']:.4f}" for k, v in r["per_transponder"].items()
                        if v["rms_true"] is not None)
        lines += [f"residual rms  {r['rms_true']:.4f} ms (true replies; {per})",
                  f"shots         {s['n_pings']}: {r['n_true']} true, {r['n_spurious']} "
                  f"spurious; {s.get('n_skipped_lines', 0)} lines skipped"]
        left = not_fitted_note(s)
        if left:
            lines.append(f"{'':<14}{left}")
    if "gradients" in s:
        lines.append(gradients_line(s))
    if "noise" in s:
        lines.append(noise_line(s))
    lines.append(f"intervals     sd = 1 standard deviation (m); "
                 f"{s.get('position_region', '')}")
    return "\n".join(lines) + "\n"
