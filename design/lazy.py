"""Package namespaces whose names are imported on first use (PEP 562).

Building the ``station`` command line imports every command module; each needs a constant or two of a package
(its example names, its default settings) but not the simulator, scikit-learn or shapely behind the rest of the
package. A package's ``__init__`` declares where each public name lives and imports it only when asked for.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping


def lazy_exports(
    package: str, sources: Mapping[str, tuple[str, ...]]
) -> tuple[Callable[[str], object], Callable[[], list[str]], dict[str, str]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package``, and its table of name -> submodule.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    sources : mapping of str to tuple of str
        Submodule name (relative to the package) -> the public names it defines.
    """
    module_of = {name: module for module, names in sources.items() for name in names}

    def __getattr__(name: str) -> object:
        module = module_of.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        setattr(sys.modules[package], name, value)  # later look-ups are plain attribute reads
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(module_of))

    return __getattr__, __dir__, module_of
