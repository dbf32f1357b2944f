"""Machine profiles as the station uses them: a built-in profile, or the station's own copy of it, or a user's file.

The built-in profiles are package data and never written. When the station measures a material (``station
calibrate material``) on a built-in profile, it writes the result into its own copy,
``<data folder>/profiles/NAME.toml``; from then on ``--profile NAME`` means that copy (delete it to go back to the
built-in). A user's profile file is written only when the user says so (``--yes``).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import platformdirs

from drivers.profiles import BUILTIN_PROFILES, MachineProfile, load_profile, profile_from_toml
from station.errors import station_errors
from station.paths import APP_NAME, HOME_VARIABLE, data_dir

__all__ = ["load_station_profile", "replace_material_table", "station_copy_path"]


@station_errors
def station_copy_path(name: str, *, create: bool = False) -> Path:
    """Where the station keeps its copy of the built-in profile ``name`` (it may not exist). Only ``create`` makes
    the data folder (and reports a folder that cannot be made): reading a profile never does."""
    if create:
        folder = data_dir()
    else:
        override = os.environ.get(HOME_VARIABLE)
        folder = Path(override) if override else Path(platformdirs.user_data_dir(APP_NAME, appauthor=False))
    return folder / "profiles" / f"{name}.toml"


@station_errors
def load_station_profile(name_or_path: str) -> MachineProfile:
    """What ``--profile`` names: a file (a file of that name in the working directory wins, as for
    :func:`drivers.profiles.load_profile`), else the station's copy of a built-in profile when it has one, else the
    built-in profile."""
    text = str(name_or_path)
    if text in BUILTIN_PROFILES and not Path(text).exists():
        copy = station_copy_path(text)
        if copy.is_file():
            return load_profile(copy)
    return load_profile(text)


def _header(line: str) -> str | None:
    """The table name of a ``[a.b]`` header line (quotes dropped), or None."""
    match = re.match(r"^\s*\[\s*([^\[\]]+?)\s*\]\s*(#.*)?$", line)
    if not match:
        return None
    return ".".join(part.strip().strip('"').strip("'") for part in match.group(1).split("."))


@station_errors
def replace_material_table(text: str, material: str, block: str, source: str) -> str:
    """``text`` (a laser profile's TOML) with the table ``[materials.MATERIAL]`` and its sub-tables replaced by
    ``block`` (appended when the profile has no such table); the result is checked by loading it.

    Raises
    ------
    drivers.profiles.ProfileError
        The result is not a valid profile (naming ``source``).
    """
    lines = text.splitlines()
    name = f"materials.{material}"
    start = next((i for i, line in enumerate(lines) if _header(line) == name), None)
    if start is None:
        result = text.rstrip("\n") + "\n\n" + block.rstrip("\n") + "\n"
    else:
        end = start + 1
        while end < len(lines):
            header = _header(lines[end])
            if header is not None and header != name and not header.startswith(name + "."):
                break
            end += 1
        # Keep the blank lines and comments that lead the next table with it.
        while end - 1 > start and (not lines[end - 1].strip() or lines[end - 1].lstrip().startswith("#")) \
                and end < len(lines):
            end -= 1
        kept_after = lines[end:]
        gap = [""] if kept_after and kept_after[0].strip() else []
        result = "\n".join(lines[:start] + block.rstrip("\n").splitlines() + gap + kept_after) + "\n"
    profile_from_toml(result, source)
    return result
