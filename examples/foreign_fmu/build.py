"""Build ``bouncing_ball.fmu``: an FMI 2.0 co-simulation FMU made without rubcosim.

It stands in for an FMU exported by another tool.  Needs gcc; the FMI headers
come with fmpy.  Usage (from the repository root)::

    .venv/bin/python examples/foreign_fmu/build.py [OUT.fmu]

The default output is ``examples/foreign_fmu/bouncing_ball.fmu``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import fmpy

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "bouncing_ball.c"
IDENTIFIER = "BouncingBall"
MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="BouncingBall"
  guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}" description="Bouncing ball with internal events"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="BouncingBall" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="true" canSerializeFMUstate="true"/>
  <UnitDefinitions><Unit name="m"/><Unit name="m/s"/><Unit name="m/s2"/></UnitDefinitions>
  <ModelVariables>
    <ScalarVariable name="h" valueReference="0" causality="output" variability="continuous"
      initial="calculated" description="height above the floor"><Real unit="m"/></ScalarVariable>
    <ScalarVariable name="v" valueReference="1" causality="output" variability="continuous"
      initial="calculated" description="upward velocity"><Real unit="m/s"/></ScalarVariable>
    <ScalarVariable name="bounces" valueReference="2" causality="output" variability="discrete"
      initial="calculated" description="bounces so far"><Integer/></ScalarVariable>
    <ScalarVariable name="g" valueReference="3" causality="parameter" variability="fixed"
      description="gravity"><Real unit="m/s2" start="9.81"/></ScalarVariable>
    <ScalarVariable name="e" valueReference="4" causality="parameter" variability="fixed"
      description="coefficient of restitution"><Real start="0.7"/></ScalarVariable>
    <ScalarVariable name="h0" valueReference="5" causality="parameter" variability="fixed"
      description="initial height"><Real unit="m" start="1.0"/></ScalarVariable>
    <ScalarVariable name="v0" valueReference="6" causality="parameter" variability="fixed"
      description="initial upward velocity"><Real unit="m/s" start="0.0"/></ScalarVariable>
    <ScalarVariable name="phase" valueReference="7" causality="output" variability="discrete"
      initial="calculated" description="rising, falling or resting"><String/></ScalarVariable>
    <ScalarVariable name="resting" valueReference="8" causality="output"
      variability="discrete" initial="calculated" description="at rest on the floor">
      <Boolean/></ScalarVariable>
    <ScalarVariable name="crash_at_step" valueReference="9" causality="parameter"
      variability="fixed" description="segfault in this fmi2DoStep call (0: never)">
      <Integer start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="1" dependencies=""/><Unknown index="2" dependencies=""/>
      <Unknown index="3" dependencies=""/><Unknown index="8" dependencies=""/>
      <Unknown index="9" dependencies=""/></Outputs>
    <InitialUnknowns><Unknown index="1" dependencies="6"/><Unknown index="2" dependencies="7"/>
      <Unknown index="3" dependencies=""/><Unknown index="8" dependencies=""/>
      <Unknown index="9" dependencies=""/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def build(out: Path) -> Path:
    """Compile the C source and pack the FMU at ``out``; returns ``out``."""
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError("gcc was not found on PATH; it is needed to build the example FMU")
    headers = Path(fmpy.__file__).parent / "c-code"
    with tempfile.TemporaryDirectory() as tmp:
        lib = Path(tmp) / f"{IDENTIFIER}.so"
        subprocess.run(
            [
                gcc,
                "-shared",
                "-fPIC",
                "-O2",
                "-I",
                str(headers),
                str(SOURCE),
                "-o",
                str(lib),
                "-lm",
            ],
            check=True,
        )
        out.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", MODEL_DESCRIPTION)
            z.write(lib, f"binaries/linux64/{IDENTIFIER}.so")
            z.write(SOURCE, "sources/bouncing_ball.c")
    return out


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "bouncing_ball.fmu"
    print(build(target))
