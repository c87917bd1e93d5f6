"""FMI 2.0 co-simulation units built with pythonfmu from :mod:`rubcosim.components`.

:mod:`.build` builds them (``rubcosim build-fmus``), :mod:`.fmi_slave` is the slave
adapter bundled into each FMU, :mod:`.native` compiles and installs the loader that lets
a non-Python host start Python.
"""
