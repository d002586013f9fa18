"""Vessel data and thruster descriptions (pure; shared with the plant). Frames and configuration checks are in
:mod:`dpbase`."""
