"""Co-simulation master coupling the FMU units.

Built in a later step of the project (see the issues); nothing is exported yet.
"""
