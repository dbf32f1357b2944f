"""Drawing-machine designs: the machines by name, and the parameters a design file holds.

The command line (``--design FILE.json``) and the screens read a design the same way, here: what ``station pattern
--json`` prints (``{"machine": ..., "params": {...}}``), a flat ``{name: value}`` mapping, or the ranked list
``station retrieve --json`` prints, from which the first design of the machine is taken.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from design.datafiles import load_json
from design.machines import declared_machine_names, get_machine
from station.errors import ServiceError, station_errors

__all__ = ["DESIGN_FILE", "declared_machine_names", "get_machine", "load_design"]

#: What a design file should be, the end of the message for a file that is not JSON.
DESIGN_FILE = ('a design: what `station pattern --json` prints, {"params": {...}}, {name: value} or the list of '
               '`station retrieve --json`')

# The machines' registry, by name, for the faces (a face names a machine; the models stay in design).
declared_machine_names = station_errors(declared_machine_names)
get_machine = station_errors(get_machine)


@station_errors
def load_design(path: str | Path, machine_name: str) -> dict[str, Any]:
    """Parameters from a design file (see the module's docstring) for the machine ``machine_name``.

    Raises
    ------
    StationError
        Not JSON (:func:`design.datafiles.load_json`'s one line: file, line and column, what was expected), not an
        object or list, ``params`` not an object, a ``machine`` other than ``machine_name``, or a
        list with no design for ``machine_name``.
    """
    path = Path(path)
    document = load_json(path, DESIGN_FILE)
    if isinstance(document, list):
        ranked = [d for d in document if isinstance(d, dict) and d.get("machine") == machine_name]
        if not ranked:
            found = sorted({str(d.get("machine")) for d in document if isinstance(d, dict)})
            raise ServiceError(f"{path}: expected a list of designs with one for {machine_name!r}, "
                               f"found machines {found}", value=str(path))
        document = ranked[0]
    if not isinstance(document, dict):
        raise ServiceError(f"{path}: expected a JSON object, got {type(document).__name__}", value=str(path))
    if "params" in document:
        machine = document.get("machine", machine_name)
        if machine != machine_name:
            raise ServiceError(f"{path}: field 'machine' is {machine!r}, but the command draws {machine_name!r}",
                               value=str(path))
        params = document["params"]
        if not isinstance(params, dict):
            raise ServiceError(f"{path}: field 'params' must be an object of name: value, got {params!r:.60}",
                               value=str(path))
    else:
        params = document
    return dict(params)
