"""The sound-speed profile a survey-in asks for (``--ssp``)."""

from __future__ import annotations

from ..exceptions import InputError


def survey_profile(raw, ssp):
    """Return the sound-speed profile ``ssp`` names for a survey.

    Parameters
    ----------
    raw : RawSurvey
    ssp : None, SoundSpeedProfile, str or path
        As for :func:`~.survey.locate_survey` (None and ``"straight"``: straight rays).

    Returns
    -------
    SoundSpeedProfile or None
        ``None`` for straight rays.

    Raises
    ------
    bayes_mpem.InputError
        When the survey lacks what ``ssp`` asks for (its own profile, a position).
    """
    from ..acoustics.profile import SoundSpeedProfile

    if ssp is None or isinstance(ssp, SoundSpeedProfile):
        return ssp
    if str(ssp) == "straight":
        return None
    if str(ssp) == "survey":
        prof = raw.header.get("ss_prof")
        if prof is None:
            raise InputError(f"ssp='survey': {raw.source} came with no sound-speed profile "
                             "(SeaGap's ss_prof.inp, GARPOS's svp.csv, GNATSS's sound_speed); "
                             "give a file or 'woa09'")
        return SoundSpeedProfile(prof["depth"], prof["sound_speed"],
                                 source=raw.header.get("ss_prof_source", "ss_prof.inp"))
    if str(ssp) == "woa09":
        if "lat" not in raw.header:
            raise InputError(f"ssp='woa09': {raw.source} has no latitude/longitude to look the "
                             "atlas up at; give a profile file")
        return SoundSpeedProfile.from_woa09(raw.header["lat"], raw.header["lon"])
    return SoundSpeedProfile.from_file(ssp)
