"""Simulated LBL surveys.

The simulator (:mod:`.simulate`), its presets (:mod:`.presets`) and the effects with which a
survey can break the paper's assumptions (:mod:`.effects`).
"""
