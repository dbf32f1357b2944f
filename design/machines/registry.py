"""Registry of drawing machines: built-ins, ``register_machine`` and the ``chaos_station.machines`` entry points.

A machine is added without editing this package in either of two ways:

* at run time, ``register_machine(MyMachine)`` (a :class:`~design.machines.base.DrawingMachine` subclass or
  instance);
* by packaging, an entry point in the group ``chaos_station.machines`` whose name is the machine's name and whose
  object is the class (or an instance), e.g. in ``pyproject.toml``::

      [project.entry-points."chaos_station.machines"]
      spirograph = "design.machines.spirograph:Spirograph"

The four built-in machines are declared exactly that way in the station's own ``pyproject.toml``. If the
distribution's metadata is not installed (running from a bare checkout), the built-ins are loaded from
:data:`BUILTIN_MACHINES`, the same table, so the station works either way. Machines are loaded on first use of the
registry; one whose entry point fails to load is left out of :func:`machine_names`, and :func:`get_machine` on
its name raises :class:`MachineRegistryError` saying why.
"""

from __future__ import annotations

import importlib
import threading
from importlib.metadata import entry_points

from design.errors import DesignError, parameter_error
from design.machines.base import DrawingMachine

#: Entry-point group scanned for machines.
ENTRY_POINT_GROUP = "chaos_station.machines"

#: The built-in machines, as entry-point values (module:attribute); mirrored in pyproject.toml.
BUILTIN_MACHINES = {
    "spirograph": "design.machines.spirograph:Spirograph",
    "elliptic_spirograph": "design.machines.elliptic_spirograph:EllipticSpirograph",
    "cycloid_drawing_machine": "design.machines.cycloid_drawing_machine:CycloidDrawingMachine",
    "hoot_nanny": "design.machines.hoot_nanny:HootNanny",
}

_registry: dict[str, DrawingMachine] = {}
_broken: dict[str, str] = {}  # name -> why its entry point could not be loaded
_discovered = False
_lock = threading.RLock()


class MachineRegistryError(DesignError):
    """A machine could not be registered or loaded (bad object, duplicate name, broken entry point)."""


def _as_instance(obj: object, origin: str) -> DrawingMachine:
    if isinstance(obj, type) and issubclass(obj, DrawingMachine):
        obj = obj()
    if not isinstance(obj, DrawingMachine):
        raise MachineRegistryError(f"{origin}: expected a DrawingMachine subclass or instance, got {obj!r}")
    if not obj.name:
        raise MachineRegistryError(f"{origin}: machine {type(obj).__name__} has no name")
    return obj


def _load_spec(spec: str) -> object:
    module_name, _, attribute = spec.partition(":")
    module = importlib.import_module(module_name)
    obj = module
    for part in attribute.split("."):
        obj = getattr(obj, part)
    return obj


def register_machine(machine: type[DrawingMachine] | DrawingMachine, *, replace: bool = False) -> DrawingMachine:
    """Register a machine (class or instance) under its ``name``; return the registered instance.

    Raises
    ------
    MachineRegistryError
        If ``machine`` is not a DrawingMachine, or its name is taken by another machine and ``replace`` is false.
    """
    instance = _as_instance(machine, "register_machine")
    _discover()
    with _lock:
        existing = _registry.get(instance.name)
        if existing is not None and type(existing) is not type(instance) and not replace:
            raise MachineRegistryError(f"a machine named {instance.name!r} is already registered")
        _broken.pop(instance.name, None)
        _registry[instance.name] = instance
    return instance


def unregister_machine(name: str) -> None:
    """Remove a machine (mainly for tests and plug-in development)."""
    _discover()
    with _lock:
        _registry.pop(name, None)
        _broken.pop(name, None)


def _discover() -> None:
    """Load the built-ins and the entry points once. A broken plug-in is not listed; asking for it says why."""
    global _discovered
    if _discovered:
        return
    with _lock:
        if _discovered:
            return
        found: dict[str, object] = dict(BUILTIN_MACHINES)
        try:
            for point in entry_points(group=ENTRY_POINT_GROUP):
                found[point.name] = point
        except Exception:  # pragma: no cover - corrupt metadata must not break the built-ins
            pass
        for name, spec in found.items():
            if name in _registry:
                continue
            try:
                obj = _load_spec(spec) if isinstance(spec, str) else spec.load()
                instance = _as_instance(obj, f"entry point {name!r}")
                if instance.name != name:
                    raise MachineRegistryError(f"entry point {name!r} loads a machine named {instance.name!r}")
            except Exception as error:
                target = spec if isinstance(spec, str) else getattr(spec, "value", spec)
                _broken[name] = f"cannot load {target}: {error}"
                continue
            _registry[name] = instance
        _discovered = True


def machine_names() -> list[str]:
    """Names of every available machine: the built-ins first (thesis order), then the others sorted."""
    _discover()
    names = set(_registry)
    builtin = [n for n in BUILTIN_MACHINES if n in names]
    return builtin + sorted(names - set(builtin))


def declared_machine_names() -> list[str]:
    """Names of the built-in and entry-point machines, without loading any of them.

    For help texts and completions, which must not pay for importing every model (and scipy); a declared
    machine whose entry point is broken is listed here but not by :func:`machine_names`.
    """
    names = set(BUILTIN_MACHINES) | set(_registry)
    try:
        names.update(point.name for point in entry_points(group=ENTRY_POINT_GROUP))
    except Exception:  # pragma: no cover - corrupt metadata must not break the built-ins
        pass
    builtin = [n for n in BUILTIN_MACHINES if n in names]
    return builtin + sorted(names - set(builtin))


def get_machine(name: str) -> DrawingMachine:
    """The machine called ``name``.

    Raises
    ------
    ParameterError
        If no machine has that name (the message lists the known ones).
    MachineRegistryError
        If its entry point exists but cannot be loaded (the message says why).
    """
    _discover()
    machine = _registry.get(name)
    if machine is not None:
        return machine
    if name in _broken:
        raise MachineRegistryError(f"machine {name!r}: {_broken[name]}")
    raise parameter_error("drawing machines", "machine", f"one of {', '.join(machine_names())}", name)


def all_machines() -> list[DrawingMachine]:
    """Every available machine, in :func:`machine_names` order."""
    return [get_machine(name) for name in machine_names()]
