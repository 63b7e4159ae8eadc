"""A quoted pass-through cell with a line break inside is kept by ``fit`` in classified.csv."""

import pandas as pd

from bayes_mpem.cli import main


def test_embedded_newline_in_a_quoted_cell_is_kept(tmp_path):
    assert main(["simulate", "--seed", "0", "--n-cycles", "60", "--out", str(tmp_path / "d")]) == 0
    p = pd.read_csv(tmp_path / "d" / "pings.csv")
    p["note"] = "plain"
    p.loc[3, "note"] = "two\nlines"
    p.loc[5, "note"] = 'a "quoted", bare\rreturn'
    p.to_csv(tmp_path / "p.csv", index=False)
    text = (tmp_path / "p.csv").read_text()
    assert '"two\nlines"' in text
    assert main(["fit", str(tmp_path / "p.csv"), "--beacons", str(tmp_path / "d" / "beacons.csv"),
                 "--out", str(tmp_path / "o")]) == 0
    c = pd.read_csv(tmp_path / "o" / "classified.csv", keep_default_na=False)
    assert c["note"][3] == "two\nlines" and c["note"][5] == 'a "quoted", bare\rreturn'
    assert len(c) == len(p) and (c["note"] == p["note"]).all()
