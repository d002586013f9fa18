"""Vessel data, thruster descriptions, frames and config validation (pure; shared with the plant)."""
