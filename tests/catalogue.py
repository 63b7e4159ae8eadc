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
    if code == 0:
        if case.command in ("fit", "sample", "diagnose", "locate") and out is not None:
            _check_marker(out, problems)
            if case.command in ("fit", "sample", "locate") and not problems:
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


class _Timeout(Exception):
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
        damaged("sample_posterior_garbage", base.sample_out, replace("posterior.nc", b"junk" * 9))
        damaged("sample_posterior_missing", base.sample_out, remove("posterior.nc"))
    for name, bad in [("folder_missing", work / "nope"), ("folder_is_file", base.pings),
                      ("folder_empty", work / "empty")]:
        if name == "folder_empty":
            bad.mkdir(parents=True, exist_ok=True)
        out.append(Case(f"plot:{name}", "plot", ["plot", bad, "--out", work / f"{name}_figs"],
                        work / f"{name}_figs"))
    out.append(Case("plot:out_is_file", "plot", ["plot", base.fit_out, "--out", base.pings], None))
    return out
