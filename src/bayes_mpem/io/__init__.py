"""Files in, validated objects out; files out. No science here.

* :mod:`~bayes_mpem.io.boundary`: what every reader shares: lines as ``grep -n``
  counts them, line shapes, the physical limits of every value;
* :mod:`~bayes_mpem.io.tables`: the pings and beacons tables (CSV, Parquet or
  DataFrame), with row and column errors; :mod:`~bayes_mpem.io.table_files` reads and
  writes the files;
* :mod:`~bayes_mpem.io.survey`: :class:`~bayes_mpem.io.survey.Survey` and
  :class:`~bayes_mpem.io.survey.BeaconData`, the validated LBL survey;
* :mod:`~bayes_mpem.io.geodesy`: WGS84 and the local east-north-up frame;
* :mod:`~bayes_mpem.io.raw`, :mod:`~bayes_mpem.io.obsrange`,
  :mod:`~bayes_mpem.io.seagap`, :mod:`~bayes_mpem.io.formats`: measured
  survey-in files (OBSrange deck-box logs, SeaGap) as a
  :class:`~bayes_mpem.io.raw.RawSurvey`;
* :mod:`~bayes_mpem.io.results`: the one writer of every output folder (all or
  nothing, ``summary.json`` last as the completion marker, valid JSON).
"""
