"""A catalogue of malformed inputs and options, and the judge of how a command answers them.

Used by ``benchmarks/malformed_catalogue.py`` (every case, counts printed) and by
``tests/cli/test_malformed.py`` (a small deterministic part, and Hypothesis-generated
corruptions). Each case is one ``bayes-mpem`` command line built on small valid files
(a simulated survey of a few hundred pings, the OBSrange and SeaGap samples, the
outputs of ``fit`` and ``sample``) with one thing broken. It is run in-process
through :func:`bayes_mpem.cli.main` with a time limit, and its answer judged
independently of the package's own checks:

* ``ok``: exit 0, and the output is complete and right: ``summary.json`` is strict
  JSON (no NaN/Infinity tokens, no ``non_finite`` entry) and lists files that exist;
  every input row is in ``classified`` (rows out = rows in, counted here from the
  file's text), each with a label, the class probabilities finite where a class is
  given; for a deck-box log, every non-blank line that is not header is accounted
  for, and each ping's line number points at the text it came from (``grep -n``).
* ``refused``: exit 2 with one ``error:`` message that names a file, line, column or
  option, and the output folder as it was before (no new complete-looking output).
* anything else is a failure: a traceback (an exception out of ``main``), another
  exit status, a run over the time limit, lost rows, non-finite output, or a folder
  that looks complete but is not the previous one.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

NAMES_WHERE = re.compile(r"line \d+|row \d+|column '|argument -|--[a-z]|RESULT_DIR|"
                         r"\.csv|\.txt|\.inp|\.json|\.nc|\.parquet|/")
PING_CLASSES = ("dp", "mp", "ol")


@dataclass
class Case:
    """One command line with one thing broken."""

    name: str
    command: str
    argv: list
    out: Path | None = None
    rows_in: int | None = None  # data rows of a pings table (None: not counted)
    survey: Path | None = None  # a deck-box log: lines accounted for
    previous: bool = False  # --out holds a complete earlier result
    # the newer surfaces (issue 27): how to judge the answer
    kind: str | None = None  # "stream", "batch", "garpos", "gnatss" (default: command)
    stream_input: Path | None = None  # the lines fed (replayed)
    stream_out: Path | None = None  # the answers (JSON lines)
    stream_map: dict | None = None  # case line -> clean line (None: the broken line)
    stream_clean: dict | None = None  # clean line -> its answer
    stream_prefix: int = 0  # lines before this number were answered by an earlier run
    state: Path | None = None  # --state FILE
    manifest: Path | None = None  # batch
    gnssa_lines: Path | None = None  # the GNSS-A file whose lines are accounted for
    slow: bool = False  # starts a Dask cluster or a long fit: not in the fast part


@dataclass
class Outcome:
    """How the command answered, and the verdict."""

    case: Case
    code: int | None
    err: str
    seconds: float
    verdict: str
    problems: list = field(default_factory=list)


def _strict_json(path: Path):
    def refuse(token):
        raise ValueError(f"{path}: non-standard JSON token {token}")
    return json.loads(path.read_text(), parse_constant=refuse)


def _snapshot(folder: Path) -> dict:
    if folder is None or not folder.exists():
        return {}
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".")}


def count_table_rows(path: Path) -> int:
    """Data rows of a CSV file counted from its text: non-blank, non-# lines minus the header."""
    text = path.read_bytes().decode("utf-8", errors="replace")
    lines = [ln for ln in text.split("\n") if ln.strip() and not ln.lstrip().startswith("#")]
    if '"' in text:  # a quoted field may span lines: count records
        import csv
        try:
            return max(len(list(csv.reader(lines))) - 1, 0)
        except csv.Error:
            pass
    return max(len(lines) - 1, 0)


def _check_marker(out: Path, problems: list) -> dict | None:
    marker = out / "summary.json"
    if not marker.exists():
        problems.append("no summary.json after exit 0")
        return None
    try:
        doc = _strict_json(marker)
    except ValueError as exc:
        problems.append(str(exc))
        return None
    if "non_finite" in doc:
        problems.append(f"non-finite output values: {doc['non_finite']}")
    missing = [f for f in doc.get("files", []) if not (out / f).exists()]
    if missing or "files" not in doc:
        problems.append(f"marker lists missing files {missing}")
    for f in doc.get("files", []):
        if f.endswith(".json") and (out / f).exists():
            try:
                _strict_json(out / f)
            except ValueError as exc:
                problems.append(str(exc))
    return doc


def _check_classified(case: Case, out: Path, problems: list) -> None:
    path = out / "classified.csv"
    if not path.exists():
        path = out / "classified.parquet"
        if not path.exists():
            problems.append("no classified table")
            return
        cls = pd.read_parquet(path)
    else:
        cls = pd.read_csv(path, dtype=str, keep_default_na=False)
    if case.rows_in is not None and len(cls) != case.rows_in:
        problems.append(f"rows in {case.rows_in} != rows out {len(cls)}")
    labels = cls["label"].astype(str)
    if (labels == "").any():
        problems.append(f"{int((labels == '').sum())} rows without a label")
    classes, columns = ((("true", "spurious"), ("p_true", "p_spurious")) if "p_true" in cls
                        else (PING_CLASSES, ("p_dp", "p_mp", "p_ol")))
    classed = labels.isin(classes).to_numpy()
    for c in columns:
        v = pd.to_numeric(cls[c], errors="coerce").to_numpy()
        if classed.any() and not pd.notna(v[classed]).all():
            problems.append(f"non-finite {c} in classified rows")
    reasons = cls["reason"].astype(str)
    unexplained = ~labels.isin(classes) & (reasons == "")
    if unexplained.any():
        problems.append(f"{int(unexplained.sum())} unclassified rows without a reason")


_HEADER_LINE = re.compile(r"\s*([A-Za-z][^:]*:.*|=+|#.*)")


def _check_survey_lines(case: Case, out: Path, problems: list) -> None:
    cls = pd.read_csv(out / "classified.csv", dtype=str, keep_default_na=False)
    text = case.survey.read_bytes().decode("utf-8", errors="replace")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
    got = [int(x) for x in cls["line"]]
    if len(set(got)) != len(got):
        problems.append("a line number appears twice in classified.csv")
    seen_ping = False
    pinged = set(int(x) for x in cls.loc[cls["label"].isin(["true", "spurious"]), "line"])
    listed = set(got)
    for i, ln in enumerate(lines, start=1):
        if not ln.strip():
            continue
        head = _HEADER_LINE.fullmatch(ln) is not None
        seen_ping = seen_ping or i in pinged
        if i not in listed and not (head and not seen_ping) and not ln.lstrip().startswith("#"):
            problems.append(f"line {i} is neither header nor in classified.csv: {ln[:60]!r}")
            break
    for _, row in cls[cls["label"].isin(["true", "spurious"])].iterrows():
        i = int(row["line"])
        ms = re.match(r"\s*(\d+(?:\.\d*)?)\s*msec", lines[i - 1]) if i <= len(lines) else None
        if ms and abs(float(ms.group(1)) / 1000 - float(row["twtt"])) > 1e-9:
            problems.append(f"classified line {i} does not point at its ping (grep -n)")
            break


def judge(case: Case, code, err: str, before: dict, raised: str | None) -> tuple[str, list]:
    """Return the verdict and its problems (see the module's description)."""
    problems = []
    if raised:
        return "traceback", [raised]
    out = case.out
    kind = case.kind or case.command
    if kind == "stream" and code == 0:
        _check_stream(case, problems)
        return ("ok" if not problems else "wrong"), problems
    if kind == "batch" and code in (0, 1):
        _check_batch(case, code, problems)
        return ("ok" if not problems else "wrong"), problems
    if kind in ("garpos", "gnatss") and code == 0:
        _check_marker(out, problems)
        if not problems:
            _check_gnssa(case, out, problems)
        return ("ok" if not problems else "wrong"), problems
    if code == 0:
        if case.command in ("fit", "sample", "diagnose", "locate", "navigate") and out is not None:
            _check_marker(out, problems)
            if case.command in ("fit", "sample", "locate", "navigate") and not problems:
                _check_classified(case, out, problems)
            if case.command == "locate" and case.survey is not None and not problems:
                _check_survey_lines(case, out, problems)
        elif case.command == "plot":
            _check_marker(out, problems)
        return ("ok" if not problems else "wrong"), problems
    if code == 2:
        msg = [ln for ln in err.splitlines() if "error:" in ln]
        if not msg:
            problems.append("exit 2 without an error: line")
        elif not NAMES_WHERE.search(err):
            problems.append(f"the message names no file, line, column or option: {msg[0]}")
        if out is not None and _snapshot(out) != before:
            problems.append("the output folder changed on a refused run")
        return ("refused" if not problems else "unclear"), problems
    return f"exit {code}", [err.strip().splitlines()[-1] if err.strip() else ""]


class _Timeout(BaseException):  # not caught by the command's own "except Exception"
    pass


def run_case(case: Case, *, limit: int = 300) -> Outcome:
    """Run one case in-process with a time limit, and judge it."""
    from bayes_mpem.cli import main

    before = _snapshot(case.out)
    err, raised, code = io.StringIO(), None, None

    def alarm(signum, frame):
        raise _Timeout(f"no answer within {limit} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(limit)
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            code = main([str(a) for a in case.argv])
    except _Timeout as exc:
        raised = f"hang: {exc}"
    except SystemExit as exc:
        code = exc.code
    except BaseException as exc:  # a traceback would have reached the user
        raised = f"{type(exc).__name__}: {exc}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    seconds = time.perf_counter() - t0
    verdict, problems = judge(case, code, err.getvalue(), before, raised)
    return Outcome(case, code, err.getvalue(), seconds, verdict, problems)


# --------------------------------------------------------------------------- the base files


@dataclass
class Base:
    """Small valid inputs every case breaks one thing of."""

    root: Path
    pings: Path
    beacons: Path
    fit_out: Path
    sample_out: Path | None
    sio: Path
    whoi: Path
    seagap: Path


def make_base(root: Path, *, with_sample: bool = True) -> Base:
    """Write the valid inputs: a simulated survey, its fit (and sample), the measured samples."""
    from bayes_mpem.cli import main
    from bayes_mpem.io.formats import sample_file

    root.mkdir(parents=True, exist_ok=True)
    sim = root / "sim"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["simulate", "--preset", "abe58", "--seed", "7", "--n-cycles", "60",
                     "--out", str(sim)]) == 0
        assert main(["fit", str(sim / "pings.csv"), "--beacons", str(sim / "beacons.csv"),
                     "--out", str(root / "fit")]) == 0
        if with_sample:
            assert main(["sample", str(sim / "pings.csv"), "--beacons", str(sim / "beacons.csv"),
                         "--out", str(root / "sample"), "--no-progress", "--seed", "1"]) == 0
    sg = root / "seagap"
    sg.mkdir(exist_ok=True)
    for name in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
        shutil.copy(sample_file(f"seagap/{name}"), sg / name)
    lines = sample_file("seagap/obsdata.inp").read_text().splitlines()[:300]
    (sg / "obsdata.inp").write_text("\n".join(lines) + "\n")
    return Base(root, sim / "pings.csv", sim / "beacons.csv", root / "fit",
                root / "sample" if with_sample else None, sample_file("obsrange/SIO_CC03.txt"),
                sample_file("obsrange/WHOI_S05.txt"), sg / "obsdata.inp")


# --------------------------------------------------------------------------- the cases

CELL_VALUES = ("", "nan", "inf", "-inf", "1e300", "-1e300", "abc", "1_000", "0x10", "1;5",
               "\u22125", "1e-400", "NaN", "--1", "1e5000", "2.5.1", "\t", "1e6", "-2e7")
COLUMNS = ("time", "beacon", "range", "x", "y", "depth")


def _write(path: Path, text, mode="w") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def table_variants(base: Base, folder: Path):
    """``(name, path)`` of corrupted pings tables (structure and cells)."""
    text = base.pings.read_text()
    lines = text.splitlines()
    header, rows = lines[0], lines[1:]
    folder.mkdir(parents=True, exist_ok=True)

    def w(name, content):
        return name, _write(folder / f"{name}.csv", content)

    out = []
    for j, col in enumerate(COLUMNS):
        for k, val in enumerate(CELL_VALUES):
            r = list(rows)
            i = (7 * j + 3 * k) % len(r)
            f = r[i].split(",")
            f[j] = val
            r[i] = ",".join(f)
            out.append(w(f"cell_{col}_{k}", "\n".join([header, *r]) + "\n"))
    body = "\n".join(rows)
    out += [
        w("empty", ""), w("header_only", header + "\n"), w("blank_only", "\n\n  \n"),
        w("bom", "\ufeff" + text), w("crlf", text.replace("\n", "\r\n")),
        w("lone_cr", text.replace("\n", "\r", 3)),
        w("formfeed_junk", "\n".join([header, rows[0], "junk\fline", *rows[1:]]) + "\n"),
        w("formfeed_in_cell", "\n".join([header, rows[0].replace(",", ",\f", 1), *rows[1:]])
          + "\n"),
        w("nul", header + "\n" + rows[0] + "\x00\n" + body + "\n"),
        w("semicolon", "\n".join(ln.replace(",", ";") for ln in lines) + "\n"),
        w("semicolon_decimal_comma", "\n".join(ln.replace(",", ";").replace(".", ",")
                                              for ln in lines) + "\n"),
        w("tabs", "\n".join(ln.replace(",", "\t") for ln in lines) + "\n"),
        w("spaces", "\n".join(ln.replace(",", " ") for ln in lines) + "\n"),
        w("comment_before_header", "# exported 2024\n" + text),
        w("comment_in_middle", "\n".join([header, *rows[:5], "# pause", *rows[5:]]) + "\n"),
        w("duplicate_column", header + ",x\n" + "\n".join(r + ",1" for r in rows) + "\n"),
        w("missing_column", "\n".join(",".join(ln.split(",")[:5]) for ln in lines) + "\n"),
        w("renamed_column", text.replace("range", "rng", 1)),
        w("reserved_column", header + ",label\n" + "\n".join(r + ",x" for r in rows) + "\n"),
        w("quoted", "\n".join([header, *[re.sub(r"^([^,]*)", r'"\1"', r) for r in rows]]) + "\n"),
        w("multiline_quoted", header + ",note\n" + "\n".join(
            r + (',"two\nlines"' if i == 3 else ",x") for i, r in enumerate(rows)) + "\n"),
        w("short_row", "\n".join([header, rows[0], rows[1].rsplit(",", 2)[0], *rows[2:]]) + "\n"),
        w("long_row", "\n".join([header, rows[0], rows[1] + ",9,9", *rows[2:]]) + "\n"),
        w("trailing_commas", "\n".join(ln + "," for ln in lines) + "\n"),
        w("blank_lines", "\n\n".join(lines) + "\n"),
        w("whitespace_lines", "\n   \n".join(lines) + "\n"),
        w("truncated_mid_line", text[: len(text) // 2]),
        w("latin1", (header + "\n" + "\n".join(rows) + "\n").encode() + b"0,1,\xe9,0,0,5\n"),
        w("unknown_beacon", "\n".join([header, rows[0].replace(",", ",", 1), *rows[1:],
                                       "1.0,9,100,0,0,5,dp"]) + "\n"),
        w("all_no_reply", "\n".join([header, *[",".join(f if i != 2 else "" for i, f in
                                                         enumerate(r.split(","))) for r in rows]])
          + "\n"),
        w("binary", bytes(range(256)) * 4),
        w("huge_line", header + "\n" + "9" * 200000 + "\n" + body + "\n"),
        w("header_spaces", " " + header.replace(",", " , ") + "\n" + body + "\n"),
        w("duplicate_rows", text + body + "\n"),
        w("negative_time", text.replace("\n0.000,", "\n-5.000,", 1)),
        w("one_beacon_few", "\n".join([header, *[r for r in rows if not r.split(",")[1] == "4"],
                                       *[r for r in rows if r.split(",")[1] == "4"][:2]]) + "\n"),
    ]
    return out


def beacon_variants(base: Base, folder: Path):
    text = base.beacons.read_text()
    lines = text.splitlines()
    folder.mkdir(parents=True, exist_ok=True)
    specs = {
        "b_empty": "", "b_header_only": lines[0] + "\n",
        "b_duplicate": text + lines[1] + "\n",
        "b_nan_x": text.replace(lines[1], ",".join([lines[1].split(",")[0], "nan",
                                                     *lines[1].split(",")[2:]])),
        "b_depth_huge": text.replace(lines[2], ",".join([*lines[2].split(",")[:3], "1e9"])),
        "b_missing_depth": "\n".join(",".join(ln.split(",")[:3]) for ln in lines) + "\n",
        "b_empty_id": text.replace(lines[1], "," + lines[1].split(",", 1)[1]),
        "b_semicolon": text.replace(",", ";"),
        "b_text_y": text.replace(lines[3], ",".join([*lines[3].split(",")[:2], "north",
                                                      lines[3].split(",")[3]])),
        "b_missing_beacon": "\n".join(lines[:-1]) + "\n",
    }
    return [(k, _write(folder / f"{k}.csv", v)) for k, v in specs.items()]


def sio_variants(base: Base, folder: Path):
    text = base.sio.read_text()
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if "msec" in ln)
    ping = lines[first + 2]

    def swap(old, new, count=1, where=first + 2):
        r = list(lines)
        r[where] = r[where].replace(old, new, count)
        return "\n".join(r) + "\n"

    specs = {
        "sio_no_separator": "\n".join(ln for ln in lines if not ln.startswith("=")) + "\n",
        "sio_lat_95": swap("Lat: 4 ", "Lat: 95 "), "sio_lon_200": swap("Lon: 132", "Lon: 200"),
        "sio_minutes_75": swap(" 52.", " 75."), "sio_zero_msec": swap(ping.split()[0], "0"),
        "sio_negative_msec": swap(ping.split()[0] + " msec", "-" + ping.split()[0] + " msec"),
        "sio_formfeed_junk": "\n".join([*lines[:first + 3], "junk\f", *lines[first + 3:]]) + "\n",
        "sio_drop_lat_123": text.replace("Drop Point (Latitude):  -4.88241",
                                         "Drop Point (Latitude):  123"),
        "sio_drop_lat_text": text.replace("Drop Point (Latitude):  -4.88241",
                                          "Drop Point (Latitude):  north"),
        "sio_no_drop_point": "\n".join(ln for ln in lines if "Drop Point" not in ln) + "\n",
        "sio_no_depth": "\n".join(ln for ln in lines if "Depth" not in ln) + "\n",
        "sio_empty": "", "sio_header_only": "\n".join(lines[:first]) + "\n",
        "sio_events_only": "\n".join(lines[:first] + [ln for ln in lines if "Event" in ln]) + "\n",
        "sio_doy_400": swap("2018:114", "2018:400"), "sio_hour_25": swap(":06:0", ":25:0"),
        "sio_crlf": text.replace("\n", "\r\n"), "sio_lone_cr": swap("Alt:", "\rAlt:"),
        "sio_huge_msec": swap(ping.split()[0], "999999999"),
        "sio_latin1": text.encode() + b"\xe9\xe8\n", "sio_nul": text + "\x00\n",
        "sio_vertical_tab": swap("Alt:", "\vAlt:"), "sio_unicode_sep": swap("Alt:", "\u2028Alt:"),
        "sio_truncated": text[: len(text) // 2],
        "sio_text_in_ping": swap("Alt: ", "Alt: x"),
        "sio_header_after_pings": "\n".join([*lines, "Site: XX"]) + "\n",
        "sio_one_ping": "\n".join(lines[:first + 1]) + "\n",
    }
    return [(k, _write(folder / f"{k}.txt", v)) for k, v in specs.items()]


def whoi_variants(base: Base, folder: Path):
    text = base.whoi.read_text()
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if ln and not ln.startswith("#"))
    f = lines[first + 1].split(",")

    def field_(i, val):
        r = list(lines)
        g = list(f)
        g[i] = val
        r[first + 1] = ",".join(g)
        return "\n".join(r) + "\n"

    specs = {
        "whoi_heading_nan": field_(6, " nan"), "whoi_heading_text": field_(6, " north"),
        "whoi_twtt_zero": field_(2, " 0"), "whoi_twtt_negative": field_(2, " -3106"),
        "whoi_twtt_nan": field_(2, " nan"), "whoi_lat_95": field_(3, " 95 35.6648 N"),
        "whoi_lon_200": field_(4, " 200 48.5082 W"), "whoi_minutes_75": field_(3, " 01 75.0 N"),
        "whoi_lat_as_lon": field_(3, " 01 35.6648 E"),
        "whoi_bad_date": field_(0, "2023-13-06 05:10:05"),
        "whoi_six_fields": field_(6, "").rstrip(",\n") + "\n",
        "whoi_rng_inf": field_(1, " inf"),
        "whoi_tat_text": text.replace("# TAT:                  13 ms", "# TAT: thirteen"),
        "whoi_tat_huge": text.replace("# TAT:                  13 ms", "# TAT: 99999 ms"),
        "whoi_speed_zero": text.replace("1500 m/s", "0 m/s"),
        "whoi_drop_lat_bad": text.replace("01 35.6114 N", "01 95.6114 N"),
        "whoi_drop_depth_text": text.replace("Drop-Point Depth (m): 2318",
                                             "Drop-Point Depth (m): deep"),
        "whoi_no_header": "\n".join(ln for ln in lines if not ln.startswith("#")) + "\n",
        "whoi_semicolon": "\n".join(ln.replace(",", ";") for ln in lines) + "\n",
        "whoi_empty": "",
    }
    return [(k, _write(folder / f"{k}.txt", v)) for k, v in specs.items()]


def seagap_variants(base: Base, folder: Path):
    lines = base.seagap.read_text().splitlines()

    def variant(name, obs=None, **companions):
        d = folder / name
        d.mkdir(parents=True, exist_ok=True)
        for comp in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
            src = base.seagap.parent / comp
            key = comp.split(".")[0].replace("-", "_")
            if key in companions:
                if companions[key] is not None:
                    _write(d / comp, companions[key])
            else:
                shutil.copy(src, d / comp)
        _write(d / "obsdata.inp", obs if obs is not None else "\n".join(lines) + "\n")
        return name, d / "obsdata.inp"

    def field_(i, val, row=5):
        r = list(lines)
        g = r[row].split()
        g[i] = val
        r[row] = " ".join(g)
        return "\n".join(r) + "\n"

    pxp = (base.seagap.parent / "pxp-ini.inp").read_text()
    return [
        variant("sg_id_1_7", field_(0, "1.7")), variant("sg_id_9", field_(0, "9")),
        variant("sg_twtt_nan", field_(1, "nan")), variant("sg_twtt_zero", field_(1, "0")),
        variant("sg_twtt_huge", field_(1, "1e9")), variant("sg_east_inf", field_(3, "inf")),
        variant("sg_heading_nan", field_(6, "nan")), variant("sg_shot_float", field_(16, "2.5")),
        variant("sg_17_fields", "\n".join([*lines[:5], " ".join(lines[5].split()[:17]),
                                           *lines[6:]]) + "\n"),
        variant("sg_formfeed", "\n".join([*lines[:5], "\f", *lines[5:]]) + "\n"),
        variant("sg_comment", "# header\n" + "\n".join(lines) + "\n"),
        variant("sg_no_pxp", pxp_ini=None), variant("sg_pxp_nan", pxp_ini=pxp.replace(
            pxp.split()[0], "nan", 1)),
        variant("sg_pxp_empty", pxp_ini=""), variant("sg_ssp_text", ss_prof="depth speed\n"),
        variant("sg_ssp_speed_0", ss_prof="0 0\n100 1500\n"),
        variant("sg_tr_ant_huge", tr_ant="1e9 0 0\n"), variant("sg_empty_obs", ""),
        variant("sg_all_unknown", "\n".join("9" + ln[1:] for ln in lines) + "\n"),
    ]


def cases(base: Base, work: Path, *, sample: bool = True) -> list[Case]:
    """Every case of the catalogue (the commands fit, sample, diagnose, locate and plot)."""
    tables = table_variants(base, work / "tables")
    beacons = beacon_variants(base, work / "beacons")
    out = []
    n = 0

    def new_out(previous=False):
        nonlocal n
        n += 1
        d = work / "out" / f"o{n}"
        if previous:
            shutil.copytree(base.fit_out, d)
        return d

    rows_base = count_table_rows(base.pings)
    for cmd, extra in (("fit", []), ("fit", ["--method", "paper", "--table-format", "parquet"]),
                       ("sample", ["--no-progress"]),
                       ("diagnose", ["--no-progress", "--effects", "range_bias", "--folds", "2"])):
        d = new_out(previous=True)
        out.append(Case(f"{cmd}:valid{'_' + extra[1] if len(extra) > 1 else ''}", cmd,
                        [cmd, base.pings, "--beacons", base.beacons, "--out", d, *extra], d,
                        rows_base, previous=True))
    for name, path, fmt in (("sio", base.sio, "obsrange"), ("whoi", base.whoi, "obsrange"),
                            ("seagap", base.seagap, "seagap")):
        d = new_out()
        out.append(Case(f"locate:valid_{name}", "locate", ["locate", path, "--format", fmt,
                                                           "--out", d], d,
                        survey=path if fmt == "obsrange" else None))
    for name, path in tables:
        d = new_out(previous=len(out) % 5 == 0)
        out.append(Case(f"fit:{name}", "fit", ["fit", path, "--beacons", base.beacons,
                                               "--out", d], d, count_table_rows(path),
                        previous=len(out) % 5 == 0))
    for name, path in beacons:
        d = new_out()
        out.append(Case(f"fit:{name}", "fit", ["fit", base.pings, "--beacons", path, "--out", d],
                        d, rows_base))
    fit_opts = [("--ci", None), ("--sigma-dp", "0"), ("--sigma-dp", "-1"), ("--sigma-dp", "nan"),
                ("--sigma-dp", "inf"), ("--pol", "0"), ("--pol", "1"), ("--pol", "nan"),
                ("--alpha", "0"), ("--alpha", "1.5"), ("--alpha", "nan"), ("--min-pings", "0"),
                ("--min-pings", "2"), ("--min-pings", "-5"), ("--min-pings", "nan"),
                ("--min-pings", "1.5"), ("--seed", "-1"), ("--seed", "1.5"), ("--seed", "abc"),
                ("--seed", "nan"), ("--method", "best"), ("--path", "zigzag"),
                ("--weights", "some"), ("--table-format", "xlsx")]
    for opt, val in fit_opts:
        if val is None:
            continue
        d = new_out()
        extra = [opt, val] + (["--method", "paper"] if opt in ("--pol", "--alpha") else [])
        out.append(Case(f"fit:{opt}={val}", "fit", ["fit", base.pings, "--beacons", base.beacons,
                                                    "--out", d, *extra], d, rows_base))
    outs = [("out_is_file", base.pings), ("out_under_file", base.pings / "sub"),
            ("out_unwritable", Path("/sys/bayes_mpem_out")), ("out_empty", "")]
    for cmd in ("fit", "sample", "diagnose"):
        for name, bad in outs:
            out.append(Case(f"{cmd}:{name}", cmd, [cmd, base.pings, "--beacons", base.beacons,
                                                   "--out", bad], None))
    # sample and diagnose: the same broken tables (they share the reader), their own options
    for cmd in ("sample", "diagnose"):
        for name, path in tables[::3] + beacons[::2]:
            d = new_out()
            is_beacons = name.startswith("b_")
            argv = ([cmd, base.pings, "--beacons", path] if is_beacons
                    else [cmd, path, "--beacons", base.beacons])
            argv += ["--out", d] + (["--no-progress"] if cmd == "sample" else
                                    ["--no-progress", "--no-figures", "--effects", "range_bias",
                                     "--folds", "2"])
            out.append(Case(f"{cmd}:{name}", cmd, argv, d,
                            rows_base if is_beacons else count_table_rows(path)))
    for opt, val in [("--ci", "1.5"), ("--ci", "1"), ("--ci", "0"), ("--ci", "nan"),
                     ("--ci", "inf"), ("--ci", "-0.1"), ("--ensembles", "0"),
                     ("--ensembles", "nan"), ("--concentration", "0"), ("--concentration", "nan"),
                     ("--concentration", "-1"), ("--priors", "flat"), ("--seed", "-1"),
                     ("--min-pings", "1"), ("--sigma-dp", "-3")]:
        d = new_out()
        out.append(Case(f"sample:{opt}={val}", "sample",
                        ["sample", base.pings, "--beacons", base.beacons, "--out", d, opt, val,
                         "--no-progress"], d, rows_base))
    for opt, val in [("--min-gain", "nan"), ("--min-gain", "inf"), ("--min-gain", "-1"),
                     ("--folds", "1"), ("--folds", "0"), ("--folds", "nan"), ("--seed", "-1"),
                     ("--min-pings", "2"), ("--effects", "gravity"), ("--path", "zigzag")]:
        d = new_out()
        out.append(Case(f"diagnose:{opt}={val}", "diagnose",
                        ["diagnose", base.pings, "--beacons", base.beacons, "--out", d, opt, val,
                         "--no-progress", "--no-figures"], d, rows_base))
    # locate
    for name, path in sio_variants(base, work / "sio") + whoi_variants(base, work / "whoi"):
        d = new_out()
        out.append(Case(f"locate:{name}", "locate", ["locate", path, "--format", "obsrange",
                                                     "--out", d], d, survey=path))
    for name, path in seagap_variants(base, work / "seagap"):
        d = new_out()
        out.append(Case(f"locate:{name}", "locate", ["locate", path, "--format", "seagap",
                                                     "--out", d], d))
    for opt, val in [("--ci", "1.5"), ("--ci", "1"), ("--ci", "nan"), ("--tat", "-1"),
                     ("--tat", "nan"), ("--tat", "1e9"), ("--speed-intervals", "-1"),
                     ("--speed-intervals", "1e9"), ("--speed-intervals", "200"),
                     ("--ssp", str(work / "nope.txt")), ("--ssp", str(work)),
                     ("--ssp", str(base.pings)), ("--format", "garmin"), ("--outliers", "many")]:
        d = new_out()
        out.append(Case(f"locate:{opt}={Path(val).name}", "locate",
                        ["locate", base.sio, "--format", "obsrange", "--out", d, opt, val], d,
                        survey=base.sio))
    for opt, val in [("--walkers", "0"), ("--walkers", "3"), ("--min-ess", "nan"),
                     ("--min-ess", "-1"), ("--seed", "-1"), ("--ci", "1.5")]:
        d = new_out()
        out.append(Case(f"locate:--sample {opt}={val}", "locate",
                        ["locate", base.sio, "--format", "obsrange", "--out", d, "--sample",
                         "--no-progress", opt, val], d, survey=base.sio))
    for name, bad in [("survey_is_folder", work), ("survey_missing", work / "nope.txt"),
                      ("survey_binary", base.root / "fit" / "summary.json")]:
        d = new_out()
        out.append(Case(f"locate:{name}", "locate", ["locate", bad, "--format", "obsrange",
                                                     "--out", d], d))
    for name, bad in outs:
        out.append(Case(f"locate:{name}", "locate", ["locate", base.sio, "--format", "obsrange",
                                                     "--out", bad], None))
    out += plot_cases(base, work / "plot")
    if not sample:
        out = [c for c in out if c.command != "sample"]
    return out


def _copy_output(src: Path, dst: Path) -> Path:
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(src, dst)
    return dst


def _p_text(d: Path) -> None:
    lines = (d / "classified.csv").read_text().split("\n")
    head = lines[0].split(",")
    row = lines[1].split(",")
    row[head.index("p_dp")] = "abc"
    lines[1] = ",".join(row)
    (d / "classified.csv").write_text("\n".join(lines))


def plot_cases(base: Base, work: Path) -> list[Case]:
    """Damaged output folders given to ``bayes-mpem plot``."""
    out = []

    def damaged(name, src, damage, extra=()):
        d = _copy_output(src, work / name)
        damage(d)
        fig_out = work / f"{name}_figs"
        out.append(Case(f"plot:{name}", "plot", ["plot", d, "--out", fig_out, *extra], fig_out))

    def cut(f, frac=0.5):
        def do(d):
            p = d / f
            p.write_bytes(p.read_bytes()[: int(len(p.read_bytes()) * frac)])
        return do

    def replace(f, text):
        def do(d):
            (d / f).write_text(text) if isinstance(text, str) else (d / f).write_bytes(text)
        return do

    def remove(f):
        return lambda d: (d / f).unlink()

    def edit_json(f, fn):
        def do(d):
            doc = json.loads((d / f).read_text())
            fn(doc)
            (d / f).write_text(json.dumps(doc))
        return do

    srcs = [("fit", base.fit_out)] + ([("sample", base.sample_out)] if base.sample_out else [])
    for kind, src in srcs:
        damaged(f"{kind}_valid", src, lambda d: None)
        damaged(f"{kind}_valid_into_itself", src, lambda d: None)
        out[-1].argv[2:4] = ["--out", out[-1].argv[1]]
        out[-1].out = Path(out[-1].argv[1])
        damaged(f"{kind}_summary_truncated", src, cut("summary.json"))
        damaged(f"{kind}_summary_empty", src, replace("summary.json", ""))
        damaged(f"{kind}_summary_list", src, replace("summary.json", "[1, 2]"))
        damaged(f"{kind}_summary_missing", src, remove("summary.json"))
        damaged(f"{kind}_classified_truncated", src, cut("classified.csv"))
        damaged(f"{kind}_classified_cut_rows", src, cut("classified.csv", 0.9))
        damaged(f"{kind}_classified_missing", src, remove("classified.csv"))
        damaged(f"{kind}_classified_garbage", src, replace("classified.csv", b"\x00\xff" * 50))
        damaged(f"{kind}_classified_p_text", src, _p_text)
        damaged(f"{kind}_no_beacons_table", src, edit_json("summary.json",
                                                           lambda doc: doc.pop("beacons_table")))
        damaged(f"{kind}_beacon_missing_key", src, edit_json(
            "summary.json", lambda doc: next(iter(doc["beacons"].values())).pop("sigma_mp")))
        damaged(f"{kind}_listed_file_missing", src, edit_json(
            "summary.json", lambda doc: doc["files"].append("gone.csv")))
        damaged(f"{kind}_unknown_beacon", src, lambda d: None, ["--beacon", "99"])
        damaged(f"{kind}_no_kind", src, edit_json("summary.json",
                                                  lambda doc: doc.pop("method", doc.pop("priors",
                                                                                        None))))
    damaged("fit_history_truncated", base.fit_out, cut("history.json"))
    damaged("fit_history_list", base.fit_out, replace("history.json", "[]"))
    if base.sample_out:
        damaged("sample_posterior_garbage", base.sample_out, replace("posterior_1.nc", b"junk" * 9))
        damaged("sample_posterior_missing", base.sample_out, remove("posterior_1.nc"))
    for name, bad in [("folder_missing", work / "nope"), ("folder_is_file", base.pings),
                      ("folder_empty", work / "empty")]:
        if name == "folder_empty":
            bad.mkdir(parents=True, exist_ok=True)
        out.append(Case(f"plot:{name}", "plot", ["plot", bad, "--out", work / f"{name}_figs"],
                        work / f"{name}_figs"))
    out.append(Case("plot:out_is_file", "plot", ["plot", base.fit_out, "--out", base.pings], None))
    return out


# =========================================================================== issue 27
# The surfaces added after the first catalogue: navigate, stream (lines, replay, state),
# batch (manifests) and the GNSS-A readers (GARPOS, GNATSS). Same rule: "ok" or "refused",
# judged from the files' text and the outputs, never by the package's own checks.


@dataclass
class Surfaces:
    """Small valid inputs of the newer surfaces."""

    root: Path
    dive: Path  # simulate --navigation: pings.csv, beacons.csv
    lines: list  # the dive's pings.csv lines, header first
    clean: dict  # stream: the answer (without "line") to each line number of the clean dive
    state: Path  # a saved stream state after the first HALF lines
    garpos: Path  # initcfg.ini
    gnatss: Path  # config.yaml
    fit_dive: Path  # a plain simulated survey (pings.csv, beacons.csv) for batch


HALF = 120
STREAM_ARGS = ("--warmup", "60", "--speed", "max")


def _quiet_main(argv):
    from bayes_mpem.cli import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main([str(a) for a in argv])


def _answers(path: Path) -> list:
    return [json.loads(s) for s in path.read_text().splitlines() if s.strip()]


def make_surfaces(root: Path) -> Surfaces:
    """Write the valid inputs of the newer surfaces (a few seconds)."""
    from bayes_mpem.io.garpos import write_garpos
    from bayes_mpem.io.gnatss import write_gnatss
    from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa

    root.mkdir(parents=True, exist_ok=True)
    dive = root / "dive"
    assert _quiet_main(["simulate", "--navigation", "--seed", "2", "--n-cycles", "50",
                        "--out", dive]) == 0
    assert _quiet_main(["simulate", "--seed", "5", "--n-cycles", "60", "--out",
                        root / "fitdive"]) == 0
    lines = (dive / "pings.csv").read_text().splitlines()
    out = root / "clean.jsonl"
    assert _quiet_main(["stream", "--beacons", dive / "beacons.csv", "--replay",
                        dive / "pings.csv", *STREAM_ARGS, "--out", out]) == 0
    clean = {a["line"]: {k: v for k, v in a.items() if k != "line"} for a in _answers(out)}
    first = root / "first_half.csv"
    first.write_text("\n".join(lines[:HALF]) + "\n")
    state = root / "state.json"
    assert _quiet_main(["stream", "--beacons", dive / "beacons.csv", "--replay", first,
                        *STREAM_ARGS, "--out", root / "first.jsonl", "--state", state]) == 0
    sim = simulate_gnssa(n_transponders=3, hours=0.2, rng=4, origin=(38.0, 143.0, 25.0))
    garpos = write_garpos(root / "garpos", sim.pings, sim.header)
    gnatss = write_gnatss(root / "gnatss", sim.pings, sim.header, transducer_delay=0.13)
    return Surfaces(root, dive, lines, clean, state, garpos, gnatss, root / "fitdive")


# --------------------------------------------------------------------------- judging them


def _data_lines(text: str) -> list:
    """``(number, line)`` of the non-blank, non-comment lines, as grep -n numbers them."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
    return [(i, ln) for i, ln in enumerate(lines, start=1)
            if ln.strip() and not ln.strip().startswith("#")]


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and v == v and abs(v) < 1e300


def _check_stream(case: Case, problems: list) -> None:
    """Every data line answered once, in order; answers sane; nothing poisoned downstream."""
    text = case.stream_input.read_bytes().decode("utf-8", errors="replace")
    expected = [i for i, _ in _data_lines(text)]
    if case.stream_prefix:
        expected = [i for i in expected if i > case.stream_prefix]
    try:
        answers = _answers(case.stream_out)
    except (OSError, ValueError) as exc:
        problems.append(f"answers unreadable: {exc}")
        return
    got = [a.get("line") for a in answers]
    if got != sorted(got) or len(set(got)) != len(got):
        problems.append("answers out of order or repeated")
    missing = sorted(set(expected) - set(got))
    header_like = [i for i in missing if re.search(r"time", dict(_data_lines(text)).get(i, ""))]
    if len(missing) > 1 or (missing and not header_like):
        problems.append(f"lines without an answer (silent loss): {missing[:5]}")
    extra = sorted(set(got) - set(expected))
    if extra:
        problems.append(f"answers to lines that are not data: {extra[:5]}")
    refused = set()
    for a in answers:
        if "error" in a:
            refused.add(a["line"])
            if f"line {a['line']}" not in a["error"] or len(a["error"]) > 2000:
                problems.append(f"line {a['line']}: the error does not name its line: "
                                f"{a['error'][:120]}")
                return
            continue
        for k in ("x", "y", "sd_x", "sd_y"):
            if not _finite(a.get(k)):
                problems.append(f"line {a.get('line')}: {k} = {a.get(k)!r}")
                return
        if a.get("label") in PING_CLASSES:
            p = [a.get("p_dp"), a.get("p_mp"), a.get("p_ol")]
            if not all(_finite(v) and -1e-9 <= v <= 1 + 1e-9 for v in p) or abs(sum(p) - 1) > 1e-6:
                problems.append(f"line {a['line']}: class probabilities {p}")
                return
    broken = [i for i, ref in case.stream_map.items() if ref is None] if case.stream_map else []
    if case.stream_map and broken and set(broken) <= refused:
        # every broken line refused: every other answer is the clean dive's, exactly
        for a in answers:
            ref = case.stream_map.get(a["line"])
            if ref is not None and ref in case.stream_clean:
                mine = {k: v for k, v in a.items() if k != "line"}
                if mine != case.stream_clean[ref]:
                    problems.append(f"line {a['line']} differs from the clean dive's answer "
                                    "after a refused line (poisoned)")
                    return
    if case.state is not None and case.state.exists():
        try:
            _strict_json(case.state)
        except ValueError as exc:
            problems.append(f"the saved state is not strict JSON: {exc}")


def _check_batch(case: Case, code: int, problems: list) -> None:
    import csv

    text = case.manifest.read_bytes().decode("utf-8", errors="replace")
    rows = [r for r in csv.reader([ln for _, ln in _data_lines(text)], skipinitialspace=True)]
    names = [r[0].strip() for r in rows[1:]]
    out = case.out
    try:
        surveys = pd.read_parquet(out / "surveys.parquet")
        failures = pd.read_parquet(out / "failures.parquet")
    except (OSError, ValueError) as exc:
        problems.append(f"no readable surveys/failures table: {exc}")
        return
    if sorted(map(str, surveys["name"])) != sorted(names):
        problems.append(f"surveys {sorted(map(str, surveys['name']))} != manifest {names}")
    failed = set(surveys.loc[surveys["status"] == "failed", "name"].astype(str))
    if (code == 1) != bool(failed):
        problems.append(f"exit {code} with {len(failed)} failed surveys")
    if set(failures["name"].astype(str)) != failed:
        problems.append("failures.parquet does not list the failed surveys")
    for name in surveys["name"].astype(str):
        folder = out / "surveys" / name
        done = name not in failed
        if done != (folder / "summary.json").exists() or done != (folder / "batch.json").exists():
            problems.append(f"survey {name}: folder does not match its status")
    classified = out / "classified"
    if classified.exists() and any(classified.iterdir()):
        got = set(pd.read_parquet(classified)["name"].astype(str))
        if got != set(surveys["name"].astype(str)) - failed:
            problems.append(f"classified names {sorted(got)} != done surveys")


def _check_gnssa(case: Case, out: Path, problems: list) -> None:
    cls = pd.read_csv(out / "classified.csv", dtype=str, keep_default_na=False)
    source = case.gnssa_lines
    text = source.read_bytes().decode("utf-8", errors="replace")
    data = _data_lines(text)
    if case.kind == "garpos" and data:
        data = data[1:]  # its header line
    if "file" in cls.columns:
        cls = cls[cls["file"] == str(source)]
    listed = {int(x) for x in cls["line"] if x.strip().lstrip("-").isdigit()}
    lost = [i for i, _ in data if i not in listed]
    if lost:
        problems.append(f"{source.name}: lines not in classified.csv (lost): {lost[:5]}")
    texts = dict(data)
    n_lines = len(text.split("\n")) - (1 if text.endswith("\n") else 0)
    beyond = sorted(i for i in listed if not 1 <= i <= n_lines)
    if beyond:
        problems.append(f"{source.name}: classified.csv names lines the file does not have "
                        f"(as grep -n counts them): {beyond[:5]}")
    if case.kind == "garpos" and data:  # each shot points at its line: the MT field is its id
        names = [c.strip() for c in _data_lines(text)[0][1].split(",")]
        mt = names.index("MT") if "MT" in names else None
        shots = cls[cls["label"].isin(["true", "spurious"])]
        for line, tp in zip(shots["line"], shots["transponder"], strict=True):
            fields = texts.get(int(line), "").split(",")
            if mt is None or len(fields) <= mt or fields[mt].strip() != tp:
                problems.append(f"classified line {line} ({tp}) does not point at its shot")
                break
    unclassed = ~cls["label"].isin(["true", "spurious"])
    if (cls.loc[unclassed, "reason"].astype(str) == "").any():
        problems.append("a row without a class has no reason")


# --------------------------------------------------------------------------- their cases

STREAM_VALUES = (*CELL_VALUES, "1e10", "99999", "-1e9", "0", '"a\rb"', "7" * 140000, "1e-300",
                 " 5 ", '"1,5"')


class _Cases:
    """Builds the cases of the newer surfaces, each in its own folder."""

    def __init__(self, s: Surfaces, work: Path):
        self.s, self.work, self.n, self.out = s, work, 0, []

    def folder(self) -> Path:
        self.n += 1
        d = self.work / f"c{self.n}"
        d.mkdir(parents=True, exist_ok=True)
        return d

    # ---------------------------------------------------------------- stream
    def stream(self, name, lines, mapping, extra=(), *, prefix=0, state=None, raw=None,
               beacons=None):
        """One stream case: ``lines`` replayed (``raw`` bytes instead, if given)."""
        d = self.folder()
        src = d / "in.csv"
        if raw is not None:
            src.write_bytes(raw)
        else:
            src.write_text("\n".join(lines) + "\n")
        st = None
        if state is not None:
            st = d / "state.json"
            st.write_bytes(state if isinstance(state, bytes) else state.encode())
        argv = ["stream", "--beacons", beacons or self.s.dive / "beacons.csv", "--replay", src,
                *STREAM_ARGS, "--out", d / "out.jsonl", *extra]
        if st is not None:
            argv += ["--state", st]
        self.out.append(Case(f"stream:{name}", "stream", argv, d, kind="stream",
                             stream_input=src, stream_out=d / "out.jsonl", stream_map=mapping,
                             stream_clean=self.s.clean, stream_prefix=prefix, state=st))

    def replaced(self, i, text):
        """The clean lines with line ``i`` (1-based) replaced: (lines, mapping)."""
        lines = list(self.s.lines)
        lines[i - 1] = text
        mapping = {k: (None if k == i else k) for k in range(1, len(lines) + 1)}
        return lines, mapping

    def inserted(self, i, text):
        lines = list(self.s.lines)
        lines.insert(i - 1, text)
        mapping = {k: (k if k < i else None if k == i else k - 1)
                   for k in range(1, len(lines) + 1)}
        return lines, mapping

    def stream_cases(self):
        s = self.s
        header = s.lines[0].split(",")
        n = len(s.lines)
        for j, col in enumerate(c for c in COLUMNS if c in header):
            jj = header.index(col)
            for k, val in enumerate(STREAM_VALUES):
                i = 2 + (11 * j + 7 * k) % (n - 1)
                f = s.lines[i - 1].split(",")
                f[jj] = val
                # a corrupted copy of line i before it: refused, it changes no other answer
                self.stream(f"{col}_{k}", *self.inserted(i, ",".join(f)))
        row = s.lines[90]
        cells = dict(zip(header, row.split(","), strict=True))
        as_json = {k: cells[k] for k in ("time", "beacon", "range", "x", "y", "depth")}
        bad_json = {
            "json_t_for_time": {**{k: v for k, v in as_json.items() if k != "time"},
                                "t": as_json["time"]},
            "json_nan": '{"time": NaN, "beacon": "1", "range": 5, "x": 0, "y": 0, "depth": 5}',
            "json_infinity": '{"time": 1, "beacon": "1", "range": Infinity, "x": 0, "y": 0, '
                             '"depth": 5}',
            "json_list": "[1, 2, 3]", "json_truncated": '{"time": 1, "beacon":',
            "json_nested": {**as_json, "x": {"v": 1}}, "json_bool": {**as_json, "range": True},
            "json_big_int": {**as_json, "time": 10 ** 400}, "json_string_nan": {**as_json,
                                                                                  "y": "nan"},
            "json_depth_neg": {**as_json, "depth": -1e9}, "json_null_time": {**as_json,
                                                                              "time": None},
            "json_unknown_beacon": {**as_json, "beacon": "B9"},
            "json_extra_keys": {**as_json, "note": "hello"},
            "json_deep": '{"a":' + "[" * 30000 + "]" * 30000 + "}",
            "json_beacon_list": {**as_json, "beacon": [1]},
            "json_beacon_object": {**as_json, "beacon": {"id": 1}},
            "json_depth_text": {**as_json, "depth": "deep"},
            "json_empty_object": "{}",
        }
        for name, obj in bad_json.items():
            text = obj if isinstance(obj, str) else json.dumps(obj)
            self.stream(name, *self.inserted(91, text))
        structural = {
            "blank_line": self.inserted(50, "   "), "comment_line": self.inserted(50, "# pause"),
            "header_again": self.inserted(100, s.lines[0]),
            "time_backwards": self.inserted(100, ",".join(
                ["0.5" if h == "time" else c for h, c in zip(header, s.lines[99].split(","),
                                                             strict=True)])),
            "duplicate_line": self.inserted(80, s.lines[78]),
            "extra_field": self.inserted(70, s.lines[69] + ",9"),
            "short_line": self.inserted(70, s.lines[69].rsplit(",", 2)[0]),
            "bare_cr": self.inserted(70, s.lines[69].replace(",", ",\r", 1)),
            "form_feed": self.inserted(70, s.lines[69].replace(",", ",\f", 1)),
            "u2028": self.inserted(70, s.lines[69].replace(",", ",\u2028", 1)),
            "nul": self.inserted(70, s.lines[69].replace(",", ",\x00", 1)),
            "huge_line": self.inserted(70, "9" * 300000),
            "unclosed_quote": self.inserted(70, s.lines[69].replace(",", ',"', 1)),
            "dead_reckoning_line": self.inserted(70, ",".join(
                "" if h in ("beacon", "range") else c
                for h, c in zip(header, s.lines[69].split(","), strict=True))),
            "semicolons": self.inserted(70, s.lines[69].replace(",", ";")),
        }
        t = header.index("time")

        def shifted(by):
            out = list(s.lines[:100])
            for ln in s.lines[100:]:
                f = ln.split(",")
                f[t] = repr(float(f[t]) + by)
                out.append(",".join(f))
            return out, {k: (k if k <= 100 else None) for k in range(1, len(out) + 1)}

        structural["pause_2h"] = shifted(7200.0)
        structural["clock_reset"] = shifted(-float(s.lines[100].split(",")[t]))
        for name, (lines, mapping) in structural.items():
            self.stream(name, lines, mapping)
        body = "\n".join(s.lines).encode()
        for name, raw in {"empty": b"", "no_header": "\n".join(s.lines[1:]).encode(),
                          "header_only": s.lines[0].encode(),
                          "crlf": body.replace(b"\n", b"\r\n"), "bom": b"\xef\xbb\xbf" + body,
                          "latin1_line": body.replace(b"\n", b"\ncaf\xe9\n", 1),
                          "no_final_newline": body, "binary": bytes(range(256)) * 8,
                          "missing_column": "\n".join(",".join(ln.split(",")[:4])
                                                      for ln in s.lines).encode()}.items():
            self.stream(name, None, None, raw=raw)

    def replay_cases(self):
        s = self.s
        header = s.lines[0].split(",")
        t = header.index("time")
        for k, val in enumerate(("1e300", "-1e300", "99999", "nan", "abc", "1e10")):
            for speed in ("1000", "realtime"):
                lines = [s.lines[0], s.lines[1], s.lines[2]]
                f = s.lines[3].split(",")
                f[t] = val
                lines += [",".join(f), s.lines[4]]
                mapping = {1: 1, 2: 2, 3: 3, 4: None, 5: 5}
                d_extra = ["--speed", speed]
                self.stream(f"replay_{k}_{speed}", lines, mapping, d_extra)

    def option_cases(self):
        s = self.s
        lines = s.lines[:40]
        mapping = {k: k for k in range(1, 41)}
        for opt, val in [("--dr-noise", "1e300"), ("--dr-noise", "1e-8"), ("--dr-noise", "1e-300"),
                         ("--dr-noise", "1e10"), ("--dr-noise", "nan"), ("--max-gap", "0"),
                         ("--max-gap", "-1"), ("--max-gap", "inf"), ("--max-gap", "1"),
                         ("--warmup", "2"), ("--warmup", "1e9"), ("--alpha", "0.5"),
                         ("--alpha", "nan"), ("--speed", "0"), ("--speed", "-1"),
                         ("--speed", "inf"), ("--speed", "nan"), ("--save-every", "-1"),
                         ("--save-every", "1"), ("--sigma-dp", "0"), ("--seed", "-1"),
                         ("--path", "zigzag"), ("--multipath", "x"), ("--append", None),
                         ("--in", "udp://nohost"), ("--out", "udp://x:99999")]:
            extra = [opt] if val is None else [opt, val]
            self.stream(f"{opt}={val}", lines, mapping, extra)
        d = self.folder()
        src = d / "in.csv"
        src.write_text("\n".join(lines) + "\n")
        for name, argv in [("replay_missing", ["--replay", d / "nope.csv"]),
                           ("replay_folder", ["--replay", d]),
                           ("out_folder", ["--replay", src, "--out", d]),
                           ("beacons_missing", ["--replay", src, "--beacons", d / "nope.csv"])]:
            full = ["stream", "--beacons", s.dive / "beacons.csv", *STREAM_ARGS, *argv]
            if "--out" not in argv:
                full += ["--out", d / "o.jsonl"]
            self.out.append(Case(f"stream:{name}", "stream", full, d, kind="stream",
                                 stream_input=src, stream_out=d / "o.jsonl"))

    def state_cases(self):
        s = self.s
        good = json.loads(s.state.read_text())
        second = [s.lines[0], *s.lines[HALF:]]
        mapping = {1: 1, **{k: HALF + k - 1 for k in range(2, len(second) + 1)}}

        def spoil(fn):
            d = json.loads(json.dumps(good))
            fn(d)
            return json.dumps(d)

        model = next(iter(good["models"]))
        cov = next(iter(good["filter"]["cov"]))
        variants = {f"drop_{k}": spoil(lambda d, k=k: d.pop(k)) for k in good}
        variants.update({
            "filter_x_null": spoil(lambda d: d["filter"].update(x=None)),
            "filter_x_text": spoil(lambda d: d["filter"].update(x="a")),
            "filter_cov_null": spoil(lambda d: d["filter"]["cov"].update({cov: None})),
            "filter_cov_huge": spoil(lambda d: d["filter"]["cov"].update({cov: 1e308})),
            "filter_list": spoil(lambda d: d.update(filter=[1, 2])),
            "model_d0_null": spoil(lambda d: d["models"][model].update(d0=None)),
            "model_weights_short": spoil(lambda d: d["models"][model].update(weights=[1.0])),
            "model_unknown_beacon": spoil(lambda d: d["models"].update(ZZ=d["models"][model])),
            "model_list": spoil(lambda d: d.update(models=[])),
            "dp_sigma_negative": spoil(lambda d: d["dp"].update(sigma=-1.0)),
            "dp_stats_null": spoil(lambda d: d["dp"].update(stats=None)),
            "options_warmup_text": spoil(lambda d: d["options"].update(warmup="x")),
            "options_dr_noise_huge": spoil(lambda d: d["options"].update(dr_noise=1e300)),
            "options_unknown_key": spoil(lambda d: d["options"].update(turbo=True)),
            "last_short": spoil(lambda d: d.update(last=[1.0])),
            "last_far_future": spoil(lambda d: d.update(last=[1e9, 0.0, 0.0])),
            "phase_other": spoil(lambda d: d.update(phase="later")),
            "phase_warmup": spoil(lambda d: d.update(phase="warmup")),
            "format_other": spoil(lambda d: d.update(format="something")),
            "version_2": spoil(lambda d: d.update(version=2)),
            "beacons_changed": spoil(lambda d: d["beacons"].update(x=[v + 5 for v in
                                                                       d["beacons"]["x"]])),
            "nan_token": json.dumps(good).replace(json.dumps(good["filter"]["x"]), "NaN", 1),
            "infinity_token": json.dumps(good).replace(json.dumps(good["filter"]["y"]),
                                                       "Infinity", 1),
            "truncated": json.dumps(good)[:200], "empty": "", "list": "[1, 2]",
            "not_json": "state", "valid": json.dumps(good),
        })
        for name, text in variants.items():
            self.stream(f"state_{name}", second, mapping, state=text, prefix=0)
        for name, raw in {"latin1": json.dumps(good).encode() + b"\xe9",
                          "binary": bytes(range(256))}.items():
            self.stream(f"state_{name}", second, mapping, state=raw)

    # ---------------------------------------------------------------- navigate
    def navigate_cases(self):
        s = self.s
        pings, beacons = s.dive / "pings.csv", s.dive / "beacons.csv"
        fake = Base(s.root, pings, beacons, None, None, None, None, None)
        for name, path in table_variants(fake, self.work / "nav_tables")[::2]:
            d = self.folder() / "o"
            self.out.append(Case(f"navigate:{name}", "navigate",
                                 ["navigate", path, "--beacons", beacons, "--out", d], d,
                                 count_table_rows(path)))
        rows = count_table_rows(pings)
        dr = self.work / "dr"
        dr.mkdir(parents=True, exist_ok=True)
        text = (s.dive / "true_track.csv").read_text() if (s.dive / "true_track.csv").exists() \
            else ""
        tlines = text.splitlines()
        dr_specs = {
            "dr_empty": "", "dr_header_only": "time,x,y\n",
            "dr_one_row": "time,x,y\n0,0,0\n",
            "dr_time_repeat": "time,x,y\n0,0,0\n132,1,1\n132,2,2\n",
            "dr_time_backwards": "time,x,y\n0,0,0\n10,1,1\n5,2,2\n",
            "dr_both_forms": "time,x,y,ve,vn\n0,0,0,1,1\n10,1,1,1,1\n",
            "dr_neither": "time,a,b\n0,0,0\n10,1,1\n",
            "dr_nan": "time,x,y\n0,0,0\n10,nan,1\n",
            "dr_velocity_huge": "time,ve,vn\n0,1e9,0\n10,1,1\n",
            "dr_x_1e300": "time,x,y\n0,0,0\n10,1e300,1\n",
            "dr_latin1": b"time,x,y\n0,0,0\n10,\xe9,1\n",
            "dr_semicolon": "time;x;y\n0;0;0\n10;1;1\n",
            "dr_short_range": "time,x,y\n0,0,0\n1,0,0\n",
        }
        if tlines:
            dr_specs["dr_true_track"] = text
        for name, content in dr_specs.items():
            p = _write(dr / f"{name}.csv", content)
            d = self.folder() / "o"
            self.out.append(Case(f"navigate:{name}", "navigate",
                                 ["navigate", pings, "--beacons", beacons, "--out", d,
                                  "--dead-reckoning", p], d, rows))
        for opt, val in [("--dr-noise", "1e300"), ("--dr-noise", "1e-8"),
                         ("--dr-noise", "1e-300"), ("--dr-noise", "1e10"), ("--dr-noise", "0"),
                         ("--start-sd", "nan"), ("--start-sd", "0"), ("--heading-sd", "inf"),
                         ("--scale-sd", "-1"), ("--sigma-dp", "0"), ("--model", "kalman"),
                         ("--path", "zigzag"), ("--multipath", "x"), ("--dr-noise", "100"),
                         ("--dr-noise", "0.0001")]:
            d = self.folder() / "o"
            self.out.append(Case(f"navigate:{opt}={val}", "navigate",
                                 ["navigate", pings, "--beacons", beacons, "--out", d, opt, val],
                                 d, rows))

    # ---------------------------------------------------------------- batch
    def batch_cases(self, scheduler: str | None):
        s = self.s
        fd = s.fit_dive
        d0 = self.work / "batch"
        d0.mkdir(parents=True, exist_ok=True)
        km = pd.read_csv(fd / "pings.csv")
        km["range"] = km["range"] / 1000.0
        km.to_csv(d0 / "km.csv", index=False)
        good = f"{fd / 'pings.csv'},{fd / 'beacons.csv'}"
        manifests = {
            "empty": b"", "blank": b"\n\n", "header_only": b"name,pings,beacons\n",
            "latin1": f"name,pings,beacons\ncaf\xe9,{good}\n".encode("latin-1"),
            "nul": b"name,pings,beacons\x00\n", "binary": bytes(range(256)),
            "missing_column": f"name,pings\nA,{fd / 'pings.csv'}\n",
            "short_row": "name,pings,beacons\nA,x.csv\n",
            "long_row": f"name,pings,beacons\nA,{good},9\n",
            "empty_name": f"name,pings,beacons\n,{good}\n",
            "slash_name": f"name,pings,beacons\na/b,{good}\n",
            "dotdot_name": f"name,pings,beacons\n..,{good}\n",
            "repeated_name": f"name,pings,beacons\nA,{good}\nA,{good}\n",
            "empty_pings": f"name,pings,beacons\nA,,{fd / 'beacons.csv'}\n",
            "unknown_option": f"name,pings,beacons,turbo\nA,{good},1\n",
            "bad_option": f"name,pings,beacons,sigma_dp\nA,{good},-1\n",
            "nan_option": f"name,pings,beacons,sigma_dp\nA,{good},nan\n",
            "bad_flag": f"name,pings,beacons,figures\nA,{good},maybe\n",
            "out_option": f"name,pings,beacons,out\nA,{good},x\n",
            "semicolons": f"name;pings;beacons\nA;{good.replace(',', ';')}\n",
            "bom": ("\ufeff" + f"name,pings,beacons\nA,{good}\n"),
            "crlf": f"name,pings,beacons\r\nA,{good}\r\n",
            "comment_and_blank": f"# archive\nname,pings,beacons\n\nA,{good}\n",
        }
        for name, content in manifests.items():
            m = _write(d0 / f"{name}.csv", content)
            out = self.folder() / "o"
            slow = name in ("bom", "crlf", "comment_and_blank")
            argv = ["batch", m, "--out", out, "--no-progress"]
            if scheduler:
                argv += ["--scheduler", scheduler]
            self.out.append(Case(f"batch:{name}", "batch", argv, out, kind="batch", manifest=m,
                                 slow=slow))
        running = {
            "valid_numeric_names": f"name,pings,beacons\n001,{good}\n010,{good}\n",
            "missing_file": f"name,pings,beacons\nA,{good}\nB,{d0 / 'nope.csv'},"
                            f"{fd / 'beacons.csv'}\n",
            "slip_km": f"name,pings,beacons\nA,{good}\nKM,{d0 / 'km.csv'},{fd / 'beacons.csv'}\n",
            "swapped": f"name,pings,beacons\nS,{fd / 'beacons.csv'},{fd / 'pings.csv'}\n",
        }
        for name, content in running.items():
            m = _write(d0 / f"{name}.csv", content)
            out = self.folder() / "o"
            argv = ["batch", m, "--out", out, "--no-progress"]
            if scheduler:
                argv += ["--scheduler", scheduler]
            self.out.append(Case(f"batch:{name}", "batch", argv, out, kind="batch", manifest=m,
                                 slow=True))
        m = d0 / "valid_numeric_names.csv"
        for opt, val in [("--workers", "-1"), ("--workers", "0"), ("--workers", "x"),
                         ("--command", "dance"), ("--scheduler", "")]:
            out = self.folder() / "o"
            self.out.append(Case(f"batch:{opt}={val}", "batch",
                                 ["batch", m, "--out", out, opt, val], out, kind="batch",
                                 manifest=m, slow=opt == "--scheduler"))

    # ---------------------------------------------------------------- GNSS-A
    def garpos_cases(self):
        s = self.s
        src = s.garpos.parent
        obs_name = s.garpos.name.replace("initcfg.ini", "obs.csv")
        svp_name = s.garpos.name.replace("initcfg.ini", "svp.csv")
        obs = (src / obs_name).read_text().split("\n")
        svp = (src / svp_name).read_text().split("\n")

        def case(name, obs_text=None, svp_text=None, ini_text=None):
            d = self.folder() / "garpos"
            shutil.copytree(src, d)
            if obs_text is not None:
                _write(d / obs_name, obs_text)
            if svp_text is not None:
                _write(d / svp_name, svp_text)
            if ini_text is not None:
                _write(d / s.garpos.name, ini_text)
            out = d.parent / "o"
            self.out.append(Case(f"garpos:{name}", "locate",
                                 ["locate", d / s.garpos.name, "--format", "garpos", "--out",
                                  out], out, kind="garpos", gnssa_lines=d / obs_name))

        def cell(row, col, value):
            r = list(obs)
            f = r[row].split(",")
            f[col] = value
            r[row] = ",".join(f)
            return "\n".join(r)

        for col, name in ((4, "TT"), (9, "ST"), (10, "ant_e0"), (13, "head0"), (16, "RT"),
                          (3, "MT")):
            for k, val in enumerate(("abc", "nan", "inf", "-1", "1e300", "2.5_0", "1_000", "",
                                     "0x10", "1\r2", "1\f2")):
                case(f"{name}_{k}", cell(6 + k, col, val))
        ini = s.garpos.read_text()
        for name, text in {"obs_crlf": "\r\n".join(obs), "obs_ff_comment":
                           "\n".join([obs[0] + "\f note", *obs[1:]]),
                           "obs_u2028": "\n".join([*obs[:8], obs[8] + "\u2028", *obs[9:]]),
                           "obs_bare_cr": "\n".join([*obs[:8], obs[8].replace(",", ",\r", 1),
                                                     *obs[9:]]),
                           "obs_empty": "", "obs_header_only": "\n".join(obs[:2]),
                           "obs_latin1": "\n".join(obs).encode() + b"\n\xe9\n",
                           "obs_nul": "\n".join(obs) + "\x00\n",
                           "obs_missing_column": "\n".join(ln.rsplit(",", 1)[0] for ln in obs),
                           "obs_truncated": "\n".join(obs)[: len("\n".join(obs)) // 2]}.items():
            case(name, obs_text=text)
        for name, text in {"svp_swapped": "\n".join([svp[0], svp[2], svp[1], *svp[3:]]),
                           "svp_repeated": "\n".join([svp[0], svp[1], svp[1], *svp[2:]]),
                           "svp_speed_0": "\n".join([svp[0], "0,0", *svp[2:]]),
                           "svp_underscore": "\n".join([svp[0], svp[1].replace(".", "_", 1),
                                                        *svp[2:]]),
                           "svp_empty": ""}.items():
            case(name, svp_text=text)
        for name, text in {"ini_lat_95": ini.replace("Latitude0   = 38.00000000",
                                                     "Latitude0   = 95"),
                           "ini_empty": "", "ini_cr": ini.replace("\n", "\r", 3),
                           "ini_no_site": ini.replace("[Site-parameter]", "[Other]")}.items():
            case(name, ini_text=text)

    def gnatss_cases(self):
        s = self.s
        src = s.gnatss.parent
        tt = (src / "pxp_tt").read_text().split("\n")
        sv = (src / "ctd_sv").read_text().split("\n")

        def case(name, **files):
            d = self.folder() / "gnatss"
            shutil.copytree(src, d)
            for f, text in files.items():
                _write(d / f, text)
            out = d.parent / "o"
            self.out.append(Case(f"gnatss:{name}", "locate",
                                 ["locate", d / "config.yaml", "--format", "gnatss", "--out",
                                  out], out, kind="gnatss", gnssa_lines=d / "pxp_tt"))

        def field_(row, k, value):
            r = list(tt)
            f = r[row].split()
            f[k] = value
            r[row] = " ".join(f)
            return "\n".join(r)

        for k, val in enumerate(("abc", "nan", "-5", "1e300", "2.5_0", "1_000", "0x10", "1\r2",
                                 "1\f2", "1\u20282")):
            case(f"tt_{k}", pxp_tt=field_(3 + k, 3, val))
            case(f"date_{k}", pxp_tt=field_(3 + k, 0, val))
        for name, text in {"sv_swapped": "\n".join([sv[1], sv[0], *sv[2:]]),
                           "sv_repeated": "\n".join([sv[0], sv[0], *sv[1:]]),
                           "sv_speed": "\n".join(["0 0", *sv[1:]]), "sv_empty": "",
                           "sv_underscore": "\n".join([sv[0].replace(".", "_", 1), *sv[1:]])
                           }.items():
            case(name, ctd_sv=text)
        for name, text in {"tt_crlf": "\r\n".join(tt), "tt_empty": "",
                           "tt_latin1": "\n".join(tt).encode() + b"\xe9\n",
                           "tt_blank_lines": "\n\n".join(tt), "tt_comment": "# x\n" + "\n".join(tt),
                           "tt_ff_line": "\n".join([*tt[:5], "\f", *tt[5:]])}.items():
            case(name, pxp_tt=text)
        cfg = s.gnatss.read_text()
        for name, text in {"cfg_empty": "",
                           "cfg_lat": cfg.replace("lat: 38.0\n", "lat: 138.0\n", 1),
                           "cfg_yaml": cfg + "  bad: [\n"}.items():
            case(name, **{"config.yaml": text})


def surface_cases(s: Surfaces, work: Path, *, scheduler: str | None = None) -> list[Case]:
    """Every case of the newer surfaces: navigate, stream, batch, GARPOS, GNATSS."""
    c = _Cases(s, work)
    c.stream_cases()
    c.replay_cases()
    c.option_cases()
    c.state_cases()
    c.navigate_cases()
    c.batch_cases(scheduler)
    c.garpos_cases()
    c.gnatss_cases()
    return c.out
