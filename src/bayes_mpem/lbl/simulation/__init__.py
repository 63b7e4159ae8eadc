"""Simulated LBL surveys."""
