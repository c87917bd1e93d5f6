"""FMI 2.0 co-simulation units (pythonfmu) wrapping :mod:`rubcosim.components`.

Built in a later step of the project (see the issues); nothing is exported yet.
"""
