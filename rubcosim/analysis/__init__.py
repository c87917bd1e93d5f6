"""Analyses on the ``fast`` engine: Poincaré maps, classification of motions,
Floquet multipliers, bifurcation sweeps, grazing, basins by cell mapping."""
