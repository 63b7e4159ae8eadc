"""An independent fuzz of the GNSS-A inputs: malformed GARPOS, GNATSS and SeaGap campaigns.

Three valid campaigns are made first (``bayes-mpem simulate --gnssa --format garpos|gnatss
--hours 0.5`` and the first 200 shots of the shipped SeaGap survey). Each case copies one,
breaks one of its files the way a user does (a truncated line, a renamed header, text in a
number, NaN, CRLF, a BOM, a missing key, an impossible value, the wrong file, a folder, ...)
and runs ``bayes_mpem.cli.main(["locate", ...])`` in a forked child, with a time limit. The
verdict:

* ``ok``: exit 0, a complete folder (``summary.json``, ``classified.csv``), every data line of
  the shots file in ``classified.csv`` (kept, or skipped with a reason), no NaN where a number
  is reported;
* ``refused``: exit 2, one line on standard error naming the file and the line, column, key or
  option the case broke, and no ``summary.json`` in the output folder;
* ``FAIL``: anything else (a traceback, another exit status, more than the time limit, a line
  lost, NaN in the outputs, a message not saying where, or a verdict the case rules out:
  e.g. a latitude of 95 degrees accepted).

Prints the counts and every FAIL; exits 1 on any FAIL::

    python benchmarks/gnssa_fuzz.py [--only SUBSTRING] [--timeout 120] [--list]
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import math
import multiprocessing as mp
import os
import re
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

# --------------------------------------------------------------------------- campaigns

GARPOS_INI, GARPOS_OBS, GARPOS_SVP = ("SIM.0000.sim-initcfg.ini", "SIM.0000.sim-obs.csv",
                                      "SIM.0000.sim-svp.csv")
SEAGAP_SHOTS = 200


def make_campaigns(root: Path) -> dict:
    """Write the three valid campaigns under ``root``; return ``{name: (folder, survey file)}``."""
    from bayes_mpem.cli import main
    from bayes_mpem.io.formats import sample_file

    out = {}
    for fmt, survey in (("garpos", GARPOS_INI), ("gnatss", "config.yaml")):
        folder = root / fmt
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(["simulate", "--gnssa", "--format", fmt, "--hours", "0.5",
                         "--out", str(folder)])
        if code:
            raise SystemExit(f"simulate --gnssa --format {fmt} failed ({code})")
        for extra in ("summary.json", "truth.json"):
            (folder / extra).unlink()
        out[fmt] = (folder, survey)
    folder = root / "seagap"
    folder.mkdir()
    for name in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
        shutil.copy(sample_file(f"seagap/{name}"), folder / name)
    lines = sample_file("seagap/obsdata.inp").read_text().splitlines(keepends=True)
    (folder / "obsdata.inp").write_text("".join(lines[:SEAGAP_SHOTS]))
    out["seagap"] = (folder, "obsdata.inp")
    return out


# --------------------------------------------------------------------------- mutations
# A mutation takes the case's folder and changes files in it; helpers work on text lines.


def read(p: Path) -> list[str]:
    """The file's lines, ``\\n`` kept."""
    return p.read_text().splitlines(keepends=True)


def write(p: Path, lines) -> None:
    """Write lines back (bytes allowed)."""
    data = "".join(lines)
    p.write_bytes(data.encode() if isinstance(data, str) else data)


def data_index(lines, fmt_file: str) -> list[int]:
    """0-based indices of the data lines of a file (no comment, blank or header line)."""
    out, header_seen = [], False
    for i, s in enumerate(lines):
        t = s.strip()
        if not t or t.startswith("#"):
            continue
        if fmt_file in ("garpos_obs", "garpos_svp") and not header_seen:
            header_seen = True
            continue
        out.append(i)
    return out


def header_index(lines) -> int:
    """0-based index of the first line that is not blank or a comment."""
    return next(i for i, s in enumerate(lines) if s.strip() and not s.lstrip().startswith("#"))


def set_field(line: str, k: int, value: str, sep=",") -> str:
    """Replace field ``k`` of a line (``sep`` None: split at blanks, joined by one space)."""
    end = "\n" if line.endswith("\n") else ""
    parts = line.rstrip("\n").split(sep)
    parts[k] = value
    return (sep or " ").join(parts) + end


def drop_field(line: str, k: int, sep=",") -> str:
    """Remove field ``k``."""
    end = "\n" if line.endswith("\n") else ""
    parts = line.rstrip("\n").split(sep)
    del parts[k]
    return (sep or " ").join(parts) + end


@dataclass
class Case:
    """One malformed campaign.

    Attributes
    ----------
    name : str
    campaign : str
        ``garpos``, ``gnatss`` or ``seagap``.
    mutate : callable
        ``mutate(folder) -> dict``: changes the files; may return ``line`` (1-based line the
        message must name), ``where`` (tokens: the message must hold one of them), ``args``
        (extra options) and ``survey`` (another file to pass).
    expect : tuple of str
        The verdicts allowed (``ok``, ``refused``).
    file : str
        The file the message must name (default: the file broken, in ``mutate``'s ``where``).
    """

    name: str
    campaign: str
    mutate: object
    expect: tuple = ("ok", "refused")
    options: list = field(default_factory=list)
    root: bool = False  # run the case as an unprivileged user (permissions)
    bad_line: bool = False  # the line the hint names must not be fitted (when ok)


CASES: list[Case] = []


def case(name, campaign, expect=("ok", "refused"), options=(), root=False):
    """Register a mutation as a case."""
    def deco(fn):
        CASES.append(Case(name, campaign, fn, tuple(expect), list(options), root))
        return fn
    return deco


def on_line(folder, name, kind, pick, fn):
    """Apply ``fn(line) -> line`` to data line number ``pick`` of ``name``; return the hint."""
    p = folder / name
    lines = read(p)
    idx = data_index(lines, kind)[pick]
    lines[idx] = fn(lines[idx])
    write(p, lines)
    return {"file": name, "line": idx + 1}


# -- generic mutations, registered for every file of every campaign

FILES = {
    "garpos": [(GARPOS_INI, "garpos_ini"), (GARPOS_OBS, "garpos_obs"), (GARPOS_SVP, "garpos_svp")],
    "gnatss": [("config.yaml", "gnatss_cfg"), ("pxp_tt", "gnatss_tt"),
               ("POS_FREED_TRANS_TWTT", "gnatss_pos"), ("ctd_sv", "gnatss_svp")],
    "seagap": [("obsdata.inp", "seagap_obs"), ("pxp-ini.inp", "seagap_pxp"),
               ("tr-ant.inp", "seagap_trant"), ("ss_prof.inp", "seagap_svp")],
}
#: the files whose lines are shots (every one must reach classified.csv)
SHOTS = {"garpos": (GARPOS_OBS, "garpos_obs"), "gnatss": ("pxp_tt", "gnatss_tt"),
         "seagap": ("obsdata.inp", "seagap_obs")}


def generic(campaign, name, kind):
    """Register the mutations every file gets."""
    def reg(tag, fn, expect=("ok", "refused"), root=False):
        CASES.append(Case(f"{campaign}:{name}:{tag}", campaign, fn, expect, [], root))

    def empty(f):
        (f / name).write_bytes(b"")
        return {"file": name}

    def blanks(f):
        (f / name).write_text("\n \n\t\n")
        return {"file": name}

    def truncated_last(f):
        data = (f / name).read_bytes().rstrip(b"\n")
        cut = data.rfind(b"\n") + 1 + max(1, (len(data) - data.rfind(b"\n")) // 2)
        (f / name).write_bytes(data[:cut])
        return {"file": name, "line": data.count(b"\n", 0, cut) + 1}

    def truncated_half(f):
        data = (f / name).read_bytes()
        cut = len(data) // 2 + 3
        (f / name).write_bytes(data[:cut])
        return {"file": name}

    def bom(f):
        (f / name).write_bytes(b"\xef\xbb\xbf" + (f / name).read_bytes())
        return {"file": name}

    def crlf(f):
        (f / name).write_bytes((f / name).read_bytes().replace(b"\n", b"\r\n"))
        return {"file": name}

    def cr_only(f):
        (f / name).write_bytes((f / name).read_bytes().replace(b"\n", b"\r"))
        return {"file": name}

    def latin1(f):
        lines = read(f / name)
        idx = data_index(lines, kind)[len(data_index(lines, kind)) // 2]
        raw = "".join(lines[:idx]).encode() + b"\xe9" + "".join(lines[idx:]).encode()
        (f / name).write_bytes(raw)
        return {"file": name, "line": idx + 1}

    def nul(f):
        lines = read(f / name)
        idx = data_index(lines, kind)[0]
        raw = "".join(lines[:idx]).encode() + b"\x00\x00" + "".join(lines[idx:]).encode()
        (f / name).write_bytes(raw)
        return {"file": name, "line": idx + 1}

    def folder_instead(f):
        (f / name).unlink()
        (f / name).mkdir()
        return {"file": name}

    def missing(f):
        (f / name).unlink()
        return {"file": name}

    def unreadable(f):
        (f / name).chmod(0)
        return {"file": name}

    def gzipped(f):
        import gzip

        (f / name).write_bytes(gzip.compress((f / name).read_bytes()))
        return {"file": name}

    def duplicated_all(f):
        (f / name).write_bytes((f / name).read_bytes() * 2)
        return {"file": name}

    def long_line(f):
        lines = read(f / name)
        idx = data_index(lines, kind)[0]
        lines.insert(idx + 1, "9" * 2_000_000 + "\n")
        write(f / name, lines)
        return {"file": name, "line": idx + 2}

    def smart_quotes(f):
        lines = read(f / name)
        idx = data_index(lines, kind)[0]
        lines.insert(idx, "\u201cnote\u201d \u2013 checked by hand\n")
        write(f / name, lines)
        return {"file": name, "line": idx + 1}

    reg("empty", empty, ("refused",))
    reg("only-blank-lines", blanks, ("refused",))
    reg("truncated-last-line", truncated_last)
    reg("truncated-mid-file", truncated_half)
    reg("bom", bom, ("ok",))
    reg("crlf", crlf, ("ok",))
    reg("cr-only", cr_only)
    reg("latin1-byte", latin1, ("refused",))
    reg("nul-bytes", nul, ("refused",))
    reg("folder-instead", folder_instead, ("refused",))
    reg("missing", missing, ("refused",) if kind not in ("seagap_trant", "seagap_svp")
        else ("ok", "refused"))
    reg("unreadable", unreadable, ("refused",), root=True)
    reg("gzipped", gzipped, ("refused",))
    reg("whole-file-twice", duplicated_all)
    reg("2MB-line", long_line)
    reg("prose-line", smart_quotes)


for _c, _files in FILES.items():
    for _n, _k in _files:
        generic(_c, _n, _k)


# -- the wrong file in place of another

def swap_cases():
    """Each file replaced by another file of its campaign (or another campaign's)."""
    for campaign, files in FILES.items():
        for name, _ in files:
            for other, _ in files:
                if other == name:
                    continue

                def fn(f, name=name, other=other):
                    shutil.copy(f / other, f / name)
                    return {"file": name}

                CASES.append(Case(f"{campaign}:{name}:is-{other}", campaign, fn, ("refused",)))


swap_cases()
#: the unbroken campaigns (set by ``main``), for the cases that take another campaign's file
CAMPAIGNS: dict = {}


def cross(campaign, name, other, other_name):
    """Register: ``name`` replaced by another campaign's ``other_name``."""
    def fn(f):
        shutil.copy(CAMPAIGNS[other][0] / other_name, f / name)
        return {"file": name}
    CASES.append(Case(f"{campaign}:{name}:is-{other}-{other_name}", campaign, fn, ("refused",)))


cross("garpos", GARPOS_OBS, "seagap", "obsdata.inp")
cross("garpos", GARPOS_SVP, "gnatss", "ctd_sv")
cross("garpos", GARPOS_INI, "gnatss", "config.yaml")
cross("gnatss", "pxp_tt", "seagap", "obsdata.inp")
cross("gnatss", "ctd_sv", "seagap", "ss_prof.inp")
cross("seagap", "obsdata.inp", "garpos", GARPOS_OBS)
cross("seagap", "ss_prof.inp", "garpos", GARPOS_SVP)


# -- GARPOS obs.csv


def obs_line(pick, fn):
    """A mutation of the ``pick``-th shot line of obs.csv."""
    return lambda f: on_line(f, GARPOS_OBS, "garpos_obs", pick, fn)


def obs_col(f, col):
    lines = read(f / GARPOS_OBS)
    return lines[header_index(lines)].rstrip("\n").split(",").index(col)


def obs_cell(col, value, pick=40, expect=("ok", "refused")):
    """Register: one obs.csv cell set to ``value``."""
    def fn(f):
        k = obs_col(f, col)
        return on_line(f, GARPOS_OBS, "garpos_obs", pick, lambda s: set_field(s, k, value))
    CASES.append(Case(f"garpos:obs:{col}={value!r}", "garpos", fn, expect))


for _col, _vals in {"TT": ["abc", "nan", "inf", "-inf", "-3.4", "0", "0.0", "1e6", "", "1,5",
                           "3.4s", "0x1p1", "1_000", "  3.42  ", "3.4e-400"],
                    "ST": ["nan", "abc", "1e300", ""], "RT": ["nan", "-5", "1e9"],
                    "ant_e0": ["nan", "inf", "abc", "1e12"], "ant_u1": ["-1e5", "nan"],
                    "head0": ["720", "nan"], "pitch1": ["95", "-91"], "roll0": ["nan", "400"],
                    "MT": ["M09", "", "m01", "M00", " M01"],
                    "flag": ["yes", "", "2", "TRUE", "nan"]}.items():
    for _v in _vals:
        obs_cell(_col, _v)


@case("garpos:obs:extra-field", "garpos")
def _(f):
    return on_line(f, GARPOS_OBS, "garpos_obs", 10, lambda s: s.rstrip("\n") + ",7\n")


@case("garpos:obs:missing-field", "garpos")
def _(f):
    return on_line(f, GARPOS_OBS, "garpos_obs", 10, lambda s: drop_field(s, 5))


@case("garpos:obs:trailing-comma-everywhere", "garpos")
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [s if s.startswith("#") else s.rstrip("\n") + ",\n" for s in lines])
    return {"file": GARPOS_OBS}


@case("garpos:obs:column-TT-removed", "garpos", ("refused",))
def _(f):
    k = obs_col(f, "TT")
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [s if s.startswith("#") else drop_field(s, k) for s in lines])
    return {"file": GARPOS_OBS, "where": ["TT"]}


@case("garpos:obs:header-renamed-TT-tt", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    h = header_index(lines)
    lines[h] = lines[h].replace(",TT,", ",tt,")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "line": h + 1}


@case("garpos:obs:header-missing", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    h = header_index(lines)
    del lines[h]
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "line": h + 1}


@case("garpos:obs:header-twice-TT", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    h = header_index(lines)
    lines[h] = lines[h].replace(",ResiTT,", ",TT,")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "line": h + 1}


@case("garpos:obs:header-repeated-mid-file", "garpos")
def _(f):
    lines = read(f / GARPOS_OBS)
    h = header_index(lines)
    lines.insert(len(lines) // 2, lines[h])
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "line": len(lines) // 2}


@case("garpos:obs:tabs-not-commas", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [s if s.startswith("#") else s.replace(",", "\t") for s in lines])
    return {"file": GARPOS_OBS}


@case("garpos:obs:semicolons-decimal-commas", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [s if s.startswith("#") else s.replace(",", ";").replace(".", ",")
                           for s in lines])
    return {"file": GARPOS_OBS}


@case("garpos:obs:quoted-fields", "garpos")
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [s if s.startswith("#") else ",".join(f'"{p}"' for p in
                                                               s.rstrip("\n").split(",")) + "\n"
                           for s in lines])
    return {"file": GARPOS_OBS}


@case("garpos:obs:one-line-duplicated", "garpos")
def _(f):
    lines = read(f / GARPOS_OBS)
    idx = data_index(lines, "garpos_obs")[30]
    lines.insert(idx + 1, lines[idx])
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "line": idx + 2}


@case("garpos:obs:shuffled", "garpos", ("ok",))
def _(f):
    import random

    lines = read(f / GARPOS_OBS)
    idx = data_index(lines, "garpos_obs")
    body = [lines[i] for i in idx]
    random.Random(3).shuffle(body)
    for i, s in zip(idx, body, strict=True):
        lines[i] = s
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "compare": True}


@case("garpos:obs:reversed", "garpos", ("ok",))
def _(f):
    lines = read(f / GARPOS_OBS)
    idx = data_index(lines, "garpos_obs")
    body = [lines[i] for i in idx][::-1]
    for i, s in zip(idx, body, strict=True):
        lines[i] = s
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS, "compare": True}


@case("garpos:obs:three-shots", "garpos")
def _(f):
    lines = read(f / GARPOS_OBS)
    idx = data_index(lines, "garpos_obs")
    write(f / GARPOS_OBS, lines[:idx[3]])
    return {"file": GARPOS_OBS}


@case("garpos:obs:header-only", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, lines[:header_index(lines) + 1])
    return {"file": GARPOS_OBS}


@case("garpos:obs:100k-header-lines", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    write(f / GARPOS_OBS, [lines[header_index(lines)]] * 100_000)
    return {"file": GARPOS_OBS}


@case("garpos:obs:all-one-transponder", "garpos")
def _(f):
    k = None
    lines = read(f / GARPOS_OBS)
    k = obs_col(f, "MT")
    keep = [s for i, s in enumerate(lines) if i not in data_index(lines, "garpos_obs")
            or s.split(",")[k] == "M01"]
    write(f / GARPOS_OBS, keep)
    return {"file": GARPOS_OBS}


@case("garpos:obs:every-shot-flagged", "garpos", ("refused",))
def _(f):
    k = obs_col(f, "flag")
    lines = read(f / GARPOS_OBS)
    for i in data_index(lines, "garpos_obs"):
        lines[i] = set_field(lines[i], k, "True")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS}


@case("garpos:obs:all-times-equal", "garpos")
def _(f):
    ks, kr, ktt = obs_col(f, "ST"), obs_col(f, "RT"), obs_col(f, "TT")
    lines = read(f / GARPOS_OBS)
    for i in data_index(lines, "garpos_obs"):
        tt = lines[i].split(",")[ktt]
        lines[i] = set_field(set_field(lines[i], ks, "100.0"), kr, f"{100 + float(tt):.6f}")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS}


@case("garpos:obs:ship-never-moves", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_OBS)
    cols = {c: obs_col(f, c) for c in ("ant_e0", "ant_n0", "ant_e1", "ant_n1")}
    for i in data_index(lines, "garpos_obs"):
        for k in cols.values():
            lines[i] = set_field(lines[i], k, "10.0")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS}


@case("garpos:obs:tt-in-ms", "garpos", ("refused",))
def _(f):
    k = obs_col(f, "TT")
    lines = read(f / GARPOS_OBS)
    for i in data_index(lines, "garpos_obs"):
        lines[i] = set_field(lines[i], k, f"{float(lines[i].split(',')[k]) * 1000:.4f}")
    write(f / GARPOS_OBS, lines)
    return {"file": GARPOS_OBS}


# -- GARPOS site file


def ini_set(key, value):
    """Set ``key = value`` in the site file; return the hint."""
    def fn(f):
        p = f / GARPOS_INI
        lines = read(p)
        for i, s in enumerate(lines):
            if s.split("=")[0].strip() == key:
                lines[i] = f" {key} = {value}\n"
                write(p, lines)
                return {"file": GARPOS_INI, "line": i + 1, "where": [key]}
        raise KeyError(key)
    return fn


def ini_case(key, value, expect=("refused",)):
    """Register a site-file value case."""
    CASES.append(Case(f"garpos:ini:{key}={value!r}", "garpos", ini_set(key, value), expect))


POS = "   -487.9274   -564.7417  -1493.9435"
for _k, _v in [("Latitude0", "95"), ("Latitude0", "abc"), ("Latitude0", "nan"),
               ("Latitude0", "38.0.0"), ("Latitude0", ""), ("Latitude0", "38,5"),
               ("Longitude0", "400"), ("Longitude0", "inf"), ("Height0", "1e6"),
               ("Stations", ""), ("Stations", "M01 M01 M03 M04"), ("Stations", "M01,M02,M03,M04"),
               ("M01_dPos", "1.0 2.0"), ("M01_dPos", f"{POS} abc 3 3"),
               ("M01_dPos", f"{POS} nan 3 3"), ("M01_dPos", f"{POS} -3 -3 -3"),
               ("M01_dPos", f"{POS} inf 3 3"), ("M01_dPos", "nan 0 -1500"),
               ("M01_dPos", "0 0 1500"), ("dCentPos", "0 0 abc"), ("dCentPos", "0 0 1e9"),
               ("ATDoffset", "1 2"), ("ATDoffset", "1 2 300"), ("ATDoffset", "nan 0 0"),
               ("datacsv", "nope.csv"), ("datacsv", ""), ("datacsv", "."),
               ("SoundSpeed", "nope.csv"), ("SoundSpeed", "")]:
    ini_case(_k, _v)
for _k, _v in [("M01_dPos", f"{POS} 0 0 0"), ("dCentPos", "0 0 0 0 0 0"),
               ("N_shot", "7"), ("Site_name", "")]:
    ini_case(_k, _v, ("ok",))
ini_case("M01_dPos", f"{POS} 3 3", ("ok", "refused"))


def ini_drop(key, expect=("refused",)):
    """Register: the line of ``key`` removed."""
    def fn(f):
        p = f / GARPOS_INI
        lines = read(p)
        lines = [s for s in lines if s.split("=")[0].strip() != key]
        write(p, lines)
        return {"file": GARPOS_INI, "where": [key]}
    CASES.append(Case(f"garpos:ini:no-{key}", "garpos", fn, expect))


for _k in ("Latitude0", "Longitude0", "Height0", "Stations", "M02_dPos", "ATDoffset", "datacsv",
           "SoundSpeed"):
    ini_drop(_k)
ini_drop("dCentPos", ("ok",))


@case("garpos:ini:duplicate-key", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_INI)
    i = next(i for i, s in enumerate(lines) if "Latitude0" in s)
    lines.insert(i + 1, " Latitude0 = 39.0\n")
    write(f / GARPOS_INI, lines)
    return {"file": GARPOS_INI, "line": i + 2}


@case("garpos:ini:section-unclosed", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_INI)
    i = next(i for i, s in enumerate(lines) if "[Site-parameter]" in s)
    lines[i] = "[Site-parameter\n"
    write(f / GARPOS_INI, lines)
    return {"file": GARPOS_INI, "line": i + 1}


@case("garpos:ini:key-without-equals", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_INI)
    i = next(i for i, s in enumerate(lines) if "Height0" in s)
    lines[i] = " Height0 0.0\n"
    write(f / GARPOS_INI, lines)
    return {"file": GARPOS_INI, "line": i + 1}


@case("garpos:ini:colon-not-equals", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_INI)
    i = next(i for i, s in enumerate(lines) if "Height0" in s)
    lines[i] = " Height0: 0.0\n"
    write(f / GARPOS_INI, lines)
    return {"file": GARPOS_INI, "line": i + 1}


@case("garpos:ini:station-absent-from-obs", "garpos")
def _(f):
    lines = read(f / GARPOS_INI)
    for i, s in enumerate(lines):
        if "Stations" in s:
            lines[i] = " Stations    = M01 M02 M03 M04 M05\n"
        if "M04_dPos" in s:
            lines.insert(i + 1, s.replace("M04", "M05"))
            break
    write(f / GARPOS_INI, lines)
    return {"file": GARPOS_INI, "where": ["M05"]}


@case("garpos:ini:obs-path-absolute", "garpos", ("ok",))
def _(f):
    return ini_set("datacsv", str(f / GARPOS_OBS))(f) and {"file": GARPOS_INI}


# -- GARPOS svp.csv


def svp_rows(f, rows, header="depth,speed"):
    (f / GARPOS_SVP).write_text(header + "\n" + "".join(f"{d},{c}\n" for d, c in rows))


@case("garpos:svp:one-row", "garpos", ("refused",))
def _(f):
    svp_rows(f, [(0, 1500)])
    return {"file": GARPOS_SVP}


@case("garpos:svp:depths-swapped", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    lines[5], lines[6] = lines[6], lines[5]
    write(f / GARPOS_SVP, lines)
    return {"file": GARPOS_SVP, "line": 7}


@case("garpos:svp:depth-repeated", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    lines.insert(6, lines[5])
    write(f / GARPOS_SVP, lines)
    return {"file": GARPOS_SVP, "line": 7}


for _v in ("0", "-1500", "15000", "nan", "abc", "", "1500 m/s", "1.5"):
    CASES.append(Case(f"garpos:svp:speed={_v!r}", "garpos",
                      (lambda v: lambda f: on_line(f, GARPOS_SVP, "garpos_svp", 10,
                                                   lambda s: set_field(s, 1, v)))(_v),
                      ("refused",)))
for _v in ("nan", "-500", "abc", "1e9"):
    CASES.append(Case(f"garpos:svp:depth={_v!r}", "garpos",
                      (lambda v: lambda f: on_line(f, GARPOS_SVP, "garpos_svp", 10,
                                                   lambda s: set_field(s, 0, v)))(_v),
                      ("refused",)))


@case("garpos:svp:header-missing", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    write(f / GARPOS_SVP, lines[1:])
    return {"file": GARPOS_SVP, "line": 1}


@case("garpos:svp:header-uppercase", "garpos")
def _(f):
    lines = read(f / GARPOS_SVP)
    lines[0] = "Depth,Speed\n"
    write(f / GARPOS_SVP, lines)
    return {"file": GARPOS_SVP, "line": 1}


@case("garpos:svp:columns-swapped", "garpos", ("ok",))
def _(f):
    lines = read(f / GARPOS_SVP)
    write(f / GARPOS_SVP, [",".join(s.rstrip("\n").split(",")[::-1]) + "\n" for s in lines])
    return {"file": GARPOS_SVP, "compare": True}


@case("garpos:svp:extra-column", "garpos", ("ok",))
def _(f):
    lines = read(f / GARPOS_SVP)
    write(f / GARPOS_SVP, [lines[0].rstrip("\n") + ",temp\n"]
          + [s.rstrip("\n") + ",4.5\n" for s in lines[1:]])
    return {"file": GARPOS_SVP, "compare": True}


@case("garpos:svp:shallower-than-array", "garpos")
def _(f):
    lines = read(f / GARPOS_SVP)
    write(f / GARPOS_SVP, lines[:6])
    return {"file": GARPOS_SVP}


@case("garpos:svp:depth-in-km", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    out = [lines[0]] + [f"{float(s.split(',')[0]) / 1000:.5f},{s.split(',')[1]}"
                        for s in lines[1:]]
    write(f / GARPOS_SVP, out)
    return {"file": GARPOS_SVP}


@case("garpos:svp:negative-depths", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    out = [lines[0]] + [f"{-float(s.split(',')[0]):.3f},{s.split(',')[1]}" for s in lines[1:]]
    write(f / GARPOS_SVP, out)
    return {"file": GARPOS_SVP}


@case("garpos:svp:space-separated", "garpos", ("refused",))
def _(f):
    lines = read(f / GARPOS_SVP)
    write(f / GARPOS_SVP, [s.replace(",", " ") for s in lines])
    return {"file": GARPOS_SVP}


# -- GNATSS


def cfg_edit(fn_edit, expect=("refused",), name=None, where=None):
    """Register an edit of the parsed config (re-dumped)."""
    def fn(f):
        import yaml

        p = f / "config.yaml"
        data = yaml.safe_load(p.read_text())
        fn_edit(data)
        p.write_text(yaml.safe_dump(data, sort_keys=False))
        return {"file": "config.yaml", "where": where}
    CASES.append(Case(f"gnatss:cfg:{name}", "gnatss", fn, expect))


def tp(k, key, value):
    def edit(d):
        d["solver"]["transponders"][k][key] = value
    return edit


for _key, _v in [("lat", 95.0), ("lat", "abc"), ("lat", ".nan"), ("lon", 400.0),
                 ("height", 100.0), ("height", "x"), ("height", None), ("internal_delay", -0.1),
                 ("internal_delay", 1e6)]:
    cfg_edit(tp(1, _key, _v), name=f"transponder.{_key}={_v!r}", where=[_key])
cfg_edit(lambda d: d["solver"]["transponders"][1].pop("lat"), name="transponder-no-lat",
         where=["lat"])
cfg_edit(lambda d: d["solver"]["transponders"][1].update(pxp_id="M01"), name="duplicate-pxp_id",
         where=["M01"])
cfg_edit(lambda d: d["solver"].update(transponders=[]), name="no-transponders",
         where=["transponders"])
cfg_edit(lambda d: d["solver"].pop("transponders"), name="transponders-key-missing",
         where=["transponders"])
cfg_edit(lambda d: d["solver"].update(transponders="M01 M02"), name="transponders-a-string",
         where=["transponders"])
cfg_edit(lambda d: d["solver"]["transponders"].__setitem__(1, "M02"), name="transponder-a-string",
         where=["transponders"])
cfg_edit(lambda d: d["solver"].pop("geoid_undulation"), name="no-geoid", where=["geoid"])
cfg_edit(lambda d: d["solver"].update(geoid_undulation="abc"), name="geoid-text",
         where=["geoid"])
cfg_edit(lambda d: d["solver"].update(gps_sigma_limit=0), name="sigma-limit-0",
         where=["gps_sigma_limit"])
cfg_edit(lambda d: d["solver"].update(gps_sigma_limit=-1), name="sigma-limit-negative",
         where=["gps_sigma_limit"])
cfg_edit(lambda d: d["solver"]["array_center"].update(lat=123.0), name="centre-lat-123",
         where=["array_center"])
cfg_edit(lambda d: d["solver"]["array_center"].update(lon="x"), name="centre-lon-text",
         where=["array_center"])
cfg_edit(lambda d: d["solver"].update(transducer_delay_time=-1), name="delay-negative",
         where=["transducer_delay_time"])
cfg_edit(lambda d: d["solver"].update(travel_times_correction=0.5), name="tt-correction-0.5",
         where=["pxp_tt", "transducer_delay_time"])
cfg_edit(lambda d: d["solver"]["input_files"]["travel_times"].update(path="nope"),
         name="tt-path-missing", where=["nope"])
cfg_edit(lambda d: d["solver"]["input_files"]["travel_times"].update(path="nope*"),
         name="tt-glob-no-match", where=["nope"])
cfg_edit(lambda d: d["solver"]["input_files"]["travel_times"].update(path="."),
         name="tt-path-folder", where=["travel_times", "'.'"])
cfg_edit(lambda d: d["solver"]["input_files"].pop("sound_speed"), name="no-sound-speed-file",
         where=["sound_speed"])
cfg_edit(lambda d: d["solver"]["input_files"].update(gps_solution=None),
         name="gps-solution-null", where=["gps_solution"])
cfg_edit(lambda d: d["solver"].update(std_dev="maybe"), name="std_dev-maybe",
         where=["std_dev"])
cfg_edit(lambda d: d["solver"]["transponders"][1].pop("pxp_id"), ("ok",), name="no-pxp_id")
cfg_edit(lambda d: d["solver"].pop("array_center"), ("ok",), name="no-array-center")


@case("gnatss:cfg:invalid-yaml", "gnatss", ("refused",))
def _(f):
    lines = read(f / "config.yaml")
    lines.insert(5, "  - pxp_id: [M09\n")
    write(f / "config.yaml", lines)
    return {"file": "config.yaml"}


@case("gnatss:cfg:tab-indent", "gnatss", ("refused",))
def _(f):
    lines = read(f / "config.yaml")
    lines[4] = lines[4].replace("    ", "\t")
    write(f / "config.yaml", lines)
    return {"file": "config.yaml", "line": 5}


@case("gnatss:cfg:key-given-twice", "gnatss", ("refused",))
def _(f):
    lines = read(f / "config.yaml")
    i = next(i for i, s in enumerate(lines) if "geoid_undulation" in s)
    lines.insert(i + 1, lines[i].replace("0.0", "35.0"))
    write(f / "config.yaml", lines)
    return {"file": "config.yaml", "line": i + 2}


@case("gnatss:cfg:a-list", "gnatss", ("refused",))
def _(f):
    (f / "config.yaml").write_text("solver:\n- a\n- b\n")
    return {"file": "config.yaml"}


def tt_line(pick, fn, expect=("ok", "refused")):
    """Register a mutation of one pxp_tt line."""
    return lambda f: on_line(f, "pxp_tt", "gnatss_tt", pick, fn)


for _k, _v in [(2, "abc"), (2, "nan"), (2, "-5"), (2, "1e12"), (3, "inf"), (2, "3.5e6"),
               (0, "32-JAN-24"), (1, "25:00:00.00"), (1, "00:00:20"), (0, "01-jan-24"),
               (0, "1.5e8"), (5, "9999999999")]:
    CASES.append(Case(f"gnatss:tt:field{_k}={_v!r}", "gnatss",
                      tt_line(20, (lambda k, v: lambda s: set_field(s, k, v, None))(_k, _v))))
CASES.append(Case("gnatss:tt:missing-column", "gnatss", tt_line(20, lambda s: drop_field(s, 3,
                                                                                       None))))
CASES.append(Case("gnatss:tt:extra-column", "gnatss",
                  tt_line(20, lambda s: s.rstrip("\n") + " 2500000\n")))
CASES.append(Case("gnatss:tt:all-zero", "gnatss",
                  tt_line(20, lambda s: " ".join(s.split()[:2] + ["0"] * 4) + "\n")))
CASES.append(Case("gnatss:tt:comma-separated", "gnatss",
                  tt_line(20, lambda s: ",".join(s.split()) + "\n")))
CASES.append(Case("gnatss:tt:j2000-time", "gnatss",
                  tt_line(20, lambda s: " ".join(["757339600.0"] + s.split()[2:]) + "\n")))


@case("gnatss:tt:one-line-duplicated", "gnatss")
def _(f):
    lines = read(f / "pxp_tt")
    lines.insert(31, lines[30])
    write(f / "pxp_tt", lines)
    return {"file": "pxp_tt", "line": 32}


@case("gnatss:tt:shuffled", "gnatss", ("ok",))
def _(f):
    import random

    lines = read(f / "pxp_tt")
    random.Random(5).shuffle(lines)
    write(f / "pxp_tt", lines)
    return {"file": "pxp_tt", "compare": True}


@case("gnatss:tt:shifted-0.5s", "gnatss", ("refused",))
def _(f):
    lines = read(f / "pxp_tt")
    write(f / "pxp_tt", [s.replace(".00 ", ".50 ", 1) for s in lines])
    return {"file": "pxp_tt", "where": ["transducer_delay_time", "align"]}


def pos_line(pick, fn):
    return lambda f: on_line(f, "POS_FREED_TRANS_TWTT", "gnatss_pos", pick, fn)


def needs_position(fn):
    """The position line broken is one a reply needs: when ok, a reply is not fitted."""
    return lambda f: {**fn(f), "not_fitted": 1}


for _k, _v in [(1, "abc"), (1, "nan"), (2, "inf"), (0, "abc"), (4, "-4.0E-04"), (4, "nan"),
               (1, "-4019.0355738")]:
    CASES.append(Case(f"gnatss:pos:field{_k}={_v!r}", "gnatss", needs_position(
        pos_line(30, (lambda k, v: lambda s: set_field(s, k, v, None))(_k, _v)))))
CASES.append(Case("gnatss:pos:missing-column", "gnatss",
                  needs_position(pos_line(30, lambda s: drop_field(s, 12, None)))))


@case("gnatss:pos:same-time-two-positions", "gnatss")
def _(f):
    lines = read(f / "POS_FREED_TRANS_TWTT")
    parts = lines[30].split()
    parts[1] = f"{float(parts[1]) + 500.0:.4f}"
    lines.insert(31, " ".join(parts) + "\n")
    write(f / "POS_FREED_TRANS_TWTT", lines)
    return {"file": "POS_FREED_TRANS_TWTT", "line": 32, "not_fitted": 1}


@case("gnatss:pos:in-km", "gnatss", ("refused",))
def _(f):
    lines = read(f / "POS_FREED_TRANS_TWTT")
    out = []
    for s in lines:
        p = s.split()
        p[1:4] = [f"{float(v) / 1000:.7f}" for v in p[1:4]]
        out.append(" ".join(p) + "\n")
    write(f / "POS_FREED_TRANS_TWTT", out)
    return {"file": "POS_FREED_TRANS_TWTT"}


@case("gnatss:svp:sign-flipped", "gnatss", ("refused",))
def _(f):
    lines = read(f / "ctd_sv")
    write(f / "ctd_sv", [f"{-float(s.split()[0]):.3f} {s.split()[1]}\n" for s in lines])
    return {"file": "ctd_sv", "line": 2}


for _k, _v in [(1, "0"), (1, "nan"), (0, "abc"), (1, "15000")]:
    CASES.append(Case(f"gnatss:svp:field{_k}={_v!r}", "gnatss",
                      (lambda k, v: lambda f: on_line(
                          f, "ctd_sv", "gnatss_svp", 10,
                          lambda s: set_field(s, k, v, None)))(_k, _v), ("refused",)))


@case("gnatss:svp:one-row", "gnatss", ("refused",))
def _(f):
    write(f / "ctd_sv", read(f / "ctd_sv")[:1])
    return {"file": "ctd_sv"}


# -- SeaGap


def sg_line(pick, fn):
    return lambda f: on_line(f, "obsdata.inp", "seagap_obs", pick, fn)


for _k, _v in [(0, "9"), (0, "1.5"), (0, "x"), (1, "nan"), (1, "-4.09"), (1, "0"), (1, "1e6"),
               (1, "abc"), (2, "inf"), (3, "1e9"), (5, "nan"), (7, "400"), (9, "1"),
               (16, "2.5"), (17, "x")]:
    CASES.append(Case(f"seagap:obs:field{_k}={_v!r}", "seagap",
                      sg_line(50, (lambda k, v: lambda s: set_field(s, k, v, None))(_k, _v))))
CASES.append(Case("seagap:obs:17-fields", "seagap", sg_line(50, lambda s: drop_field(s, 4, None))))
CASES.append(Case("seagap:obs:19-fields", "seagap", sg_line(50, lambda s: s.rstrip() + " 1\n")))
CASES.append(Case("seagap:obs:commas", "seagap",
                  sg_line(50, lambda s: ",".join(s.split()) + "\n")))
CASES.append(Case("seagap:obs:tabs", "seagap", sg_line(50, lambda s: "\t".join(s.split()) + "\n"),
                  ("ok",)))
CASES.append(Case("seagap:obs:first-line-17-fields", "seagap",
                  sg_line(0, lambda s: drop_field(s, 4, None))))
CASES.append(Case("seagap:obs:first-line-twtt-nan", "seagap",
                  sg_line(0, lambda s: set_field(s, 1, "nan", None))))


@case("seagap:obs:shuffled", "seagap", ("ok",))
def _(f):
    import random

    lines = read(f / "obsdata.inp")
    random.Random(7).shuffle(lines)
    write(f / "obsdata.inp", lines)
    return {"file": "obsdata.inp", "compare": True}


@case("seagap:obs:one-line-duplicated", "seagap")
def _(f):
    lines = read(f / "obsdata.inp")
    lines.insert(41, lines[40])
    write(f / "obsdata.inp", lines)
    return {"file": "obsdata.inp", "line": 42}


@case("seagap:obs:header-line", "seagap")
def _(f):
    lines = read(f / "obsdata.inp")
    lines.insert(0, "pxp twtt t_tx e n u head pitch roll t_rx e n u head pitch roll shot flag\n")
    write(f / "obsdata.inp", lines)
    return {"file": "obsdata.inp", "line": 1}


@case("seagap:pxp:five-columns", "seagap", ("refused",))
def _(f):
    return on_line(f, "pxp-ini.inp", "seagap_pxp", 1, lambda s: drop_field(s, 5, None))


@case("seagap:pxp:up-positive", "seagap", ("refused",))
def _(f):
    return on_line(f, "pxp-ini.inp", "seagap_pxp", 1, lambda s: set_field(s, 2, "2683.2", None))


@case("seagap:pxp:text", "seagap", ("refused",))
def _(f):
    return on_line(f, "pxp-ini.inp", "seagap_pxp", 2, lambda s: set_field(s, 0, "abc", None))


@case("seagap:pxp:nan", "seagap", ("refused",))
def _(f):
    return on_line(f, "pxp-ini.inp", "seagap_pxp", 2, lambda s: set_field(s, 1, "nan", None))


@case("seagap:pxp:three-transponders", "seagap")
def _(f):
    lines = read(f / "pxp-ini.inp")
    write(f / "pxp-ini.inp", lines[:3])
    return {"file": "pxp-ini.inp"}


@case("seagap:trant:two-numbers", "seagap", ("refused",))
def _(f):
    (f / "tr-ant.inp").write_text("0.37 17.7\n")
    return {"file": "tr-ant.inp", "line": 1}


@case("seagap:trant:two-lines", "seagap", ("refused",))
def _(f):
    (f / "tr-ant.inp").write_text("0.37 17.7 -11.5\n1.0 2.0 3.0\n")
    return {"file": "tr-ant.inp", "line": 2}


@case("seagap:trant:huge", "seagap", ("refused",))
def _(f):
    (f / "tr-ant.inp").write_text("0.37 17.7 -11500\n")
    return {"file": "tr-ant.inp"}


@case("seagap:svp:one-row", "seagap", ("refused",))
def _(f):
    write(f / "ss_prof.inp", read(f / "ss_prof.inp")[:1])
    return {"file": "ss_prof.inp"}


@case("seagap:svp:depths-swapped", "seagap", ("refused",))
def _(f):
    lines = read(f / "ss_prof.inp")
    lines[5], lines[6] = lines[6], lines[5]
    write(f / "ss_prof.inp", lines)
    return {"file": "ss_prof.inp", "line": 7}


@case("seagap:svp:depth-repeated", "seagap", ("refused",))
def _(f):
    lines = read(f / "ss_prof.inp")
    lines.insert(6, lines[5])
    write(f / "ss_prof.inp", lines)
    return {"file": "ss_prof.inp", "line": 7}


@case("seagap:svp:speed-0", "seagap", ("refused",))
def _(f):
    return on_line(f, "ss_prof.inp", "seagap_svp", 8, lambda s: set_field(s, 1, "0", None))


@case("seagap:svp:shallower-than-array", "seagap")
def _(f):
    write(f / "ss_prof.inp", read(f / "ss_prof.inp")[:10])
    return {"file": "ss_prof.inp"}


# -- the command line around the files


@case("garpos:cli:survey-is-folder", "garpos", ("refused",))
def _(f):
    return {"survey": ".", "file": "in", "where": ["folder", "directory"]}


@case("garpos:cli:survey-missing", "garpos", ("refused",))
def _(f):
    return {"survey": "nope.ini", "file": "nope.ini"}


@case("garpos:cli:format-gnatss-forced", "garpos", ("refused",))
def _(f):
    return {"args": ["--format", "gnatss"], "file": GARPOS_INI}


@case("gnatss:cli:format-garpos-forced", "gnatss", ("refused",))
def _(f):
    return {"args": ["--format", "garpos"], "file": "config.yaml"}


@case("seagap:cli:format-garpos-forced", "seagap", ("refused",))
def _(f):
    return {"args": ["--format", "garpos"], "file": "obsdata.inp"}


@case("garpos:cli:obs-passed-as-survey", "garpos", ("refused",))
def _(f):
    return {"survey": GARPOS_OBS, "file": GARPOS_OBS}


@case("gnatss:cli:pxp_tt-passed-as-survey", "gnatss", ("refused",))
def _(f):
    return {"survey": "pxp_tt", "file": "pxp_tt"}


#: the cases whose changed line is still a valid shot (every other changed shot line is broken
#: and must not be fitted)
VALID_LINES = {"garpos:obs:TT='  3.42  '", "garpos:obs:MT=' M01'", "gnatss:tt:field0='01-jan-24'",
               "gnatss:tt:field2='3.5e6'", "gnatss:tt:j2000-time", "seagap:obs:tabs"}
for _c in CASES:
    _file = SHOTS[_c.campaign][0]
    _c.bad_line = _c.name not in VALID_LINES and (
        _c.name.startswith(("garpos:obs:", "gnatss:tt:", "seagap:obs:"))
        or _c.name.startswith(f"{_c.campaign}:{_file}:"))

# a few cases also with the posterior (--sample, a short chain)
SAMPLE = ["--sample", "--min-ess", "20", "--walkers", "16", "--no-progress", "--seed", "1"]
for _name in ("garpos:obs:TT='nan'", "garpos:obs:MT='M09'", "garpos:obs:shuffled",
              "gnatss:tt:field2='abc'", "seagap:obs:field1='-4.09'"):
    _base = next(c for c in CASES if c.name == _name)
    CASES.append(Case(_name + "+sample", _base.campaign, _base.mutate, _base.expect, SAMPLE,
                      bad_line=_base.bad_line))


# --------------------------------------------------------------------------- judging


def shot_lines(path: Path, kind: str) -> list[int] | None:
    """1-based numbers of the data lines of the shots file as ``grep -n`` counts them."""
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    text = text.removeprefix("\ufeff")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    idx = data_index([s.rstrip("\r") for s in lines], kind)
    return [i + 1 for i in idx]


def run_child(argv, conn, unprivileged):
    """Run the command line in this (forked) process; send back status, stderr, seconds."""
    if unprivileged and os.geteuid() == 0:
        os.setgid(65534)
        os.setuid(65534)
    from bayes_mpem.cli import main

    err, out = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 2
    except BaseException as exc:  # noqa: BLE001 - the verdict reports it
        import traceback

        err.write("Traceback (escaped main):\n" + traceback.format_exc())
        code = -1
        del exc
    conn.send((code, err.getvalue(), out.getvalue(), time.perf_counter() - t0))
    conn.close()


def run_case(c: Case, campaigns: dict, work: Path, timeout: float, baseline: dict):
    """Run one case; return ``(verdict, detail, seconds)``."""
    src, survey = campaigns[c.campaign]
    folder = work / "in"
    shutil.copytree(src, folder)
    hint = c.mutate(folder) or {}
    out = work / "out"
    target = folder / hint.get("survey", survey)
    argv = ["locate", str(target), "--out", str(out), *c.options, *hint.get("args", [])]
    if c.root:
        for p in (work, folder):
            p.chmod(0o777)
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=run_child, args=(argv, send, c.root))
    t0 = time.perf_counter()
    proc.start()
    send.close()
    if not recv.poll(timeout):
        proc.kill()
        proc.join()
        return "FAIL", f"no answer within {timeout:g} s", time.perf_counter() - t0
    try:
        code, err, _, _ = recv.recv()
    except EOFError:
        proc.join()
        return "FAIL", f"the process died (exit {proc.exitcode})", time.perf_counter() - t0
    proc.join()
    secs = time.perf_counter() - t0
    if "Traceback" in err:
        return "FAIL", "traceback: " + err.strip().splitlines()[-1][:300], secs
    if code == 0:
        verdict, detail = judge_ok(c, out, folder, hint, baseline)
    elif code == 2:
        verdict, detail = judge_refused(c, out, err, hint, survey)
    else:
        return "FAIL", f"exit {code}: {err.strip()[-300:]}", secs
    if verdict != "FAIL" and verdict not in c.expect:
        msg = err.strip().splitlines()[-1] if err.strip() else ""
        return "FAIL", f"{verdict}, expected {'/'.join(c.expect)}: {msg[:300]}", secs
    return verdict, detail, secs


def judge_ok(c, out, folder, hint, baseline):
    """Exit 0: complete folder, every shot line in classified.csv, no NaN where numbers are."""
    if not (out / "summary.json").is_file() or not (out / "classified.csv").is_file():
        return "FAIL", "exit 0 without summary.json and classified.csv"
    text = (out / "summary.json").read_text()
    if re.search(r"\bNaN\b|Infinity", text):
        return "FAIL", "NaN or Infinity in summary.json"
    summary = json.loads(text)
    bad = [k for k in summary.get("non_finite", []) if not k.startswith(("timings",))]
    if bad and bad != baseline.get(c.campaign, {}).get("non_finite"):
        return "FAIL", f"non-finite values in summary.json: {bad[:6]}"
    name, kind = SHOTS[c.campaign]
    with open(out / "classified.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    shots = Path(folder / name)
    seen = {int(r["line"]) for r in rows
            if "file" not in r or not r["file"] or Path(r["file"]).name == name}
    expected = shot_lines(shots, kind)
    lost = [n for n in (expected or []) if n not in seen]
    if lost:
        return "FAIL", f"{len(lost)} line(s) of {name} not in classified.csv: {lost[:5]}"
    for r in rows:
        if r["label"] in ("true", "spurious"):
            for k in ("p_true", "twtt", "residual_ms"):
                v = r.get(k)
                if v is not None and (v == "" or not math.isfinite(float(v))):
                    return "FAIL", f"line {r['line']}: {k} is {v!r} in classified.csv"
        elif not r.get("reason"):
            return "FAIL", f"line {r['line']}: label {r['label']!r} without a reason"
    if c.bad_line and hint.get("line") and hint.get("file") == name:
        fitted = [r for r in rows if int(r["line"]) == hint["line"]
                  and r["label"] in ("true", "spurious")]
        if fitted:
            return "FAIL", f"line {hint['line']} was broken and fitted all the same"
    if hint.get("compare") and "--sample" not in c.options:  # a chain's order-dependent
        ref = baseline[c.campaign]["centre"]
        got = [summary["array_centre"]["enu"][k]["mean"] for k in ("east", "north", "up")]
        d = max(abs(a - b) for a, b in zip(ref, got, strict=True))
        if d > 1e-3:
            return "FAIL", f"the array centre moved {d:.4f} m from the unbroken campaign's"
    n_skip = sum(r["label"] not in ("true", "spurious") for r in rows)
    if n_skip < hint.get("not_fitted", 0):
        return "FAIL", f"{n_skip} rows not fitted; a broken line was used all the same"
    return "ok", f"{len(rows)} rows, {n_skip} not fitted"


def judge_refused(c, out, err, hint, survey):
    """Exit 2: one line naming the file and where; no complete-looking folder."""
    lines = [s for s in err.strip().splitlines() if s]
    msg = lines[-1] if lines else ""
    if (out / "summary.json").exists():
        return "FAIL", "exit 2 but summary.json written"
    if not msg.startswith("bayes-mpem locate: error:"):
        return "FAIL", f"not a one-line error: {err.strip()[:300]!r}"
    file = hint.get("file", survey)
    if file not in msg:
        return "FAIL", f"the message does not name {file}: {msg[:300]}"
    line = hint.get("line")
    where = hint.get("where") or []
    lines_ok = (line, line + 1) if file == "config.yaml" and line else (line,)  # YAML: next
    if line is not None and not any(re.search(rf"\bline {n}\b", msg) for n in lines_ok) \
            and not any(w in msg for w in where):
        return "FAIL", f"the message does not name line {line}: {msg[:300]}"
    if where and line is None and not any(w in msg for w in where):
        return "FAIL", f"the message names none of {where}: {msg[:300]}"
    return "refused", msg


def baselines(campaigns, work, timeout):
    """Run the unbroken campaigns: the centre and the non-finite keys each case compares with."""
    out = {}
    for name in campaigns:
        c = Case(f"{name}:baseline", name, lambda f: {}, ("ok",))
        d = work / f"base-{name}"
        d.mkdir()
        verdict, detail, _ = run_case(c, campaigns, d, timeout, {name: {"centre": None}})
        if verdict != "ok":
            raise SystemExit(f"the unbroken {name} campaign: {verdict} {detail}")
        s = json.loads((d / "out" / "summary.json").read_text())
        enu = s["array_centre"]["enu"]
        out[name] = {"centre": [enu[k]["mean"] for k in ("east", "north", "up")],
                     "non_finite": [k for k in s.get("non_finite", [])
                                    if not k.startswith("timings")] or None}
    return out


def main(argv=None):
    """Run the fuzz; print the counts and every FAIL; return 1 on any FAIL."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="run the cases whose name holds this text")
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--list", action="store_true", help="list the cases and stop")
    ap.add_argument("--verbose", action="store_true", help="print every case's verdict")
    args = ap.parse_args(argv)
    cases = [c for c in CASES if args.only in c.name]
    if args.list:
        print("\n".join(c.name for c in cases))
        return 0
    import encodings.utf_8_sig  # noqa: F401 - loaded before the forks (some run unprivileged)

    import matplotlib  # noqa: F401

    import bayes_mpem.cli.survey_in  # noqa: F401
    import bayes_mpem.survey_in.array_survey  # noqa: F401

    t0 = time.perf_counter()
    counts, fails = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        root.chmod(0o755)  # the permission cases run as an unprivileged user
        campaigns = make_campaigns(root / "campaigns")
        CAMPAIGNS.update(campaigns)
        base = baselines(campaigns, root, args.timeout)
        for k, c in enumerate(cases):
            work = root / f"case{k}"
            work.mkdir()
            verdict, detail, secs = run_case(c, campaigns, work, args.timeout, base)
            counts[verdict] = counts.get(verdict, 0) + 1
            if verdict == "FAIL":
                fails.append((c.name, detail))
            if args.verbose or verdict == "FAIL":
                print(f"{verdict:8s} {c.name} ({secs:.1f} s): {detail}", flush=True)
            shutil.rmtree(work, ignore_errors=True)
    print(f"\n{len(cases)} cases in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    for name, detail in fails:
        print(f"FAIL {name}: {detail}")
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
