"""The scenarios shipped with the package (``scenarios/`` of the repository, installed as
``rubcosim.scenario_files``): find one by name, list them with their descriptions."""

from __future__ import annotations

import tomllib
from importlib.util import find_spec
from pathlib import Path

SUFFIX = ".toml"


def scenario_dir() -> Path:
    """The folder of the bundled scenarios: the installed package data, else the
    repository's ``scenarios/`` beside the ``rubcosim`` source folder."""
    try:
        spec = find_spec("rubcosim.scenario_files")
    except ImportError:  # pragma: no cover - a broken install
        spec = None
    for folder in spec.submodule_search_locations or () if spec else ():
        if any(Path(folder).glob(f"*{SUFFIX}")):
            return Path(folder)
    return Path(__file__).resolve().parents[1] / "scenarios"


def bundled_scenarios() -> dict[str, str]:
    """Every bundled scenario's name and its ``[scenario] description``, sorted by name."""
    out = {}
    for path in sorted(scenario_dir().glob(f"*{SUFFIX}")):
        try:
            meta = tomllib.loads(path.read_text(encoding="utf-8")).get("scenario", {})
        except (tomllib.TOMLDecodeError, UnicodeDecodeError):  # pragma: no cover
            meta = {}
        out[path.stem] = str(meta.get("description", "")) if isinstance(meta, dict) else ""
    return out


def scenario_path(name_or_path: str | Path) -> Path | None:
    """The file of a scenario given as a path, or as a bundled name (``"impact_duffing"``
    or ``"impact_duffing.toml"``) when no such file exists here; ``None`` when neither
    exists."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    text = str(name_or_path)
    if "/" not in text and "\\" not in text and not path.is_dir():
        stem = text[: -len(SUFFIX)] if text.endswith(SUFFIX) else text
        bundled = scenario_dir() / f"{stem}{SUFFIX}"
        if stem and bundled.is_file():
            return bundled
    return None
