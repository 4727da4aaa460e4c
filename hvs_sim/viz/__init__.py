"""Visualisation: rerun logging and matplotlib figures. Reads loop records; the core never imports it."""
