"""Campaigns: many lockstep runs sampled from a spec, and DP capability analysis (composition layer).

Like :mod:`sim_plant.bench`, this package composes the plant and the controller (docs/design.md §1):
:mod:`.spec` (the campaign file → the list of runs), :mod:`.engine` (the runs on local worker processes or a
Dask cluster, resumable), :mod:`.outputs` (``campaign.csv``, ``campaign.json``, plots) and
:mod:`.capability` (DNV-ST-0111-style capability plots, Level 1 static and Level 3 time-domain).
"""
