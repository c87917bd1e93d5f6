"""rubcosim: nonsmooth rotor/stator rub-impact dynamics and its co-simulation."""

__version__ = "0.1.0"
