"""Co-simulation master coupling the units.

So far :mod:`.fmu_unit` (any FMI 2.0 co-simulation FMU driven by variable name); the
master algorithms come next (see the issues).
"""
