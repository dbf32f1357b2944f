"""The simulated physical world (``sim://world``): a maker who places parts with human error, and physics that
differ from what the scenario assumes.

It is the last twin the station needs to run its whole loop without a table: the station hands it plain data (the
parts' poses as the guide draws them, the moves a check asks for, the scenario's material values) and asks where
the parts really are and which physics really hold. ``drivers`` never imports ``design``: running the contraption
under the hidden physics is the station's job (:mod:`station.services.world`).

URL options (``sim://world?seed=3&place_mm=2&place_deg=2&fix_mm=0.5&fix_deg=0.5&highlight=0.5``)
----------------------------------------------------------------------------------------------
``seed`` (whole number, default 0: everything random in this world follows from it), ``place_mm`` / ``place_deg``
(standard deviation of the maker's error per axis and of heading when placing a part from the guide, default 2 and
2), ``fix_mm`` / ``fix_deg`` (the same when moving a part as a check's instruction says, default 0.5 and 0.5),
``highlight`` (factor on the placing error when the projector highlights the part, 0..1, default 0.5),
``friction`` (``lo,hi``: the range of the factor on every friction, rolling and spinning friction, default
0.7,1.3), ``restitution`` (the half-width of the uniform shift of every restitution, default 0.15), ``damping``
(``lo,hi``: the range of the factor on linear and angular damping, default 0.5,2) and ``name`` (share one world
between the opens of that name, as ``sim://camera?name=`` does). An unknown option or a bad value is one
:class:`drivers.errors.SimConfigError` line naming it.

Seeds
-----
Every random draw has its own stream from :class:`numpy.random.SeedSequence` of the world seed and what it is for
(a hidden value: its name; a placement: the attempt and the part's name; a correction: the attempt, the round and
the part's name; a run: the attempt), so a draw never depends on the order of the others: an attempt replayed after
an interruption places every part exactly as it did.
"""

from __future__ import annotations

import math
import threading
import urllib.parse
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from drivers.errors import SimConfigError
from drivers.sim.shared import SharedTwins, bounded_number

__all__ = ["SimulatedWorld", "forget_worlds", "parse_world_options", "sim_world", "world_named"]

#: Sane bounds of hidden material values, by parameter (after the draw): a friction above 2 or a restitution of 1
#: is no material on a makerspace table.
BOUNDS = {"friction": (0.0, 2.0), "rolling_friction": (0.0, 0.5), "spinning_friction": (0.0, 0.5),
          "restitution": (0.0, 0.99), "linear_damping": (0.0, 10.0), "angular_damping": (0.0, 10.0)}
_FRICTIONS = ("friction", "rolling_friction", "spinning_friction")
_DAMPINGS = ("linear_damping", "angular_damping")

_NUMBERS = {  # option: (lowest, highest, what it takes)
    "place_mm": (0.0, 100.0, "a standard deviation in mm from 0 to 100"),
    "place_deg": (0.0, 90.0, "a standard deviation in degrees from 0 to 90"),
    "fix_mm": (0.0, 100.0, "a standard deviation in mm from 0 to 100"),
    "fix_deg": (0.0, 90.0, "a standard deviation in degrees from 0 to 90"),
    "highlight": (0.0, 1.0, "a factor from 0 to 1"),
    "restitution": (0.0, 1.0, "a half-width from 0 to 1"),
}
_RANGES = {"friction": (0.0, 10.0), "damping": (0.0, 100.0)}  # option: (lowest, highest) of lo,hi
_OPTIONS = ("seed", "name", *_NUMBERS, *_RANGES)
_DEFAULTS: dict[str, Any] = {"seed": 0, "name": "", "place_mm": 2.0, "place_deg": 2.0, "fix_mm": 0.5,
                             "fix_deg": 0.5, "highlight": 0.5, "friction": (0.7, 1.3), "restitution": 0.15,
                             "damping": (0.5, 2.0)}

# What each stream of random numbers is for (the first word of its SeedSequence entropy after the seed).
_PHYSICS, _PLACE, _FIX, _RUN = 1, 2, 3, 4

_SHARED: SharedTwins[SimulatedWorld] = SharedTwins("world")


def _key(text: str) -> int:
    """A stable number for a name (Python's hash() changes between processes)."""
    return zlib.crc32(text.encode("utf-8"))


class SimulatedWorld:
    """The physical world twin: hidden physics and a simulated maker's hands.

    Parameters
    ----------
    url : str
        ``sim://world`` with its options (module docstring).

    Attributes
    ----------
    seed : int
        The world's seed.
    options : dict
        The URL's options with their defaults.
    attempt : int or None
        The attempt the parts were last placed for (None before the first :meth:`place`).
    """

    #: Worlds are not sized; :class:`drivers.sim.shared.SharedTwins` compares sizes of shared twins.
    size = (0, 0)

    def __init__(self, url: str = "sim://world", **_: Any) -> None:
        self.url = str(url).strip()
        self.options = parse_world_options(self.url)
        self.name: str = self.options["name"]
        self.seed: int = self.options["seed"]
        self.attempt: int | None = None
        self._hidden: dict[str, float] = {}
        self._placed: dict[str, dict] = {}
        self._opens = 0
        self._lock = threading.RLock()

    # -- the device protocol ---------------------------------------------------------------------------------

    def open(self) -> None:
        """Open it (a shared twin counts its opens)."""
        with self._lock:
            self._opens += 1

    def close(self) -> None:
        """Close one open; closing twice is harmless."""
        with self._lock:
            self._opens = max(0, self._opens - 1)

    def state(self) -> str:
        """The probe line: ``"open: simulated world, seed 3"``."""
        self.open()
        return f"open: simulated world, seed {self.seed}"

    # -- hidden physics ----------------------------------------------------------------------------------------

    def _rng(self, *words: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence([self.seed, *words]))

    def draw_physics(self, nominal: Mapping[str, float],
                     bounds: Mapping[str, tuple[float, float]] | None = None) -> None:
        """Draw the hidden material values around the scenario's.

        Parameters
        ----------
        nominal : mapping
            ``{"wood.friction": 0.5, ...}``: the scenario's values (``MATERIAL.PARAM``).
        bounds : mapping, optional
            ``{"wood.friction": (0.3, 0.8)}``: where a value must stay besides :data:`BOUNDS` (a scenario's
            uncertain range: its simulator refuses values outside it).

        Notes
        -----
        Each value has its own stream (the world seed and the value's name), so a value drawn for a name is the same
        whichever other names are drawn with it: the same world seed gives the same hidden physics.
        """
        hidden: dict[str, float] = {}
        for name, value in nominal.items():
            param = str(name).rsplit(".", 1)[-1]
            if param not in BOUNDS:
                raise SimConfigError(f"world {self.url}: draw_physics: unknown parameter {name!r}; expected "
                                     f"MATERIAL.PARAM with PARAM one of {', '.join(BOUNDS)}")
            u = float(self._rng(_PHYSICS, _key(str(name))).uniform())
            if param in _FRICTIONS:
                lo, hi = self.options["friction"]
                drawn = float(value) * (lo + (hi - lo) * u)
            elif param in _DAMPINGS:
                lo, hi = self.options["damping"]
                drawn = float(value) * (lo + (hi - lo) * u)
            else:
                half = self.options["restitution"]
                drawn = float(value) + half * (2.0 * u - 1.0)
            low, high = BOUNDS[param]
            if bounds and name in bounds:
                low, high = max(low, float(bounds[name][0])), min(high, float(bounds[name][1]))
            hidden[str(name)] = float(min(max(drawn, low), high))
        with self._lock:
            self._hidden = hidden

    def hidden_physics(self) -> dict[str, float]:
        """The hidden material values (for the runner the station builds and for bench reports ONLY: the rest of the
        station must learn them from trials)."""
        with self._lock:
            return dict(self._hidden)

    # -- the maker's hands --------------------------------------------------------------------------------------

    def place(self, parts: Sequence[Mapping], *, attempt: int, highlighted: bool = False) -> None:
        """Place every part anew for ``attempt``, each where the guide draws it plus the maker's error.

        Parameters
        ----------
        parts : sequence of mappings
            ``[{"name", "center_mm": [u, v], "heading_deg"}]`` as the guide draws them.
        attempt : int
            The attempt (0, 1, ...): with the part's name and the world seed, it seeds the error.
        highlighted : bool
            The projector highlights each part as it is placed: the error is scaled by ``highlight``.
        """
        factor = self.options["highlight"] if highlighted else 1.0
        placed = {}
        for part in parts:
            name, (u, v), heading = _pose(part, self.url, "place")
            rng = self._rng(_PLACE, int(attempt), _key(name))
            du, dv = rng.normal(0.0, self.options["place_mm"] * factor, 2)
            dh = rng.normal(0.0, self.options["place_deg"] * factor)
            placed[name] = {"center_mm": [u + float(du), v + float(dv)], "heading_deg": heading + float(dh)}
        with self._lock:
            self.attempt = int(attempt)
            self._placed = placed

    def apply(self, moves: Sequence[Mapping], *, round: int) -> None:  # noqa: A002 (the contract's name)
        """Move parts as a check's instructions say, with the maker's (smaller) error.

        Parameters
        ----------
        moves : sequence of mappings
            ``[{"name", "du_mm", "dv_mm", "dheading_deg"}]``: designed minus measured, what the instruction says.
        round : int
            The check round (1, 2, ...): with the attempt, the part's name and the world seed, it seeds the error.
        """
        with self._lock:
            if self.attempt is None:
                raise SimConfigError(f"world {self.url}: apply: no parts placed yet (place() them first)")
            placed = {k: {"center_mm": list(p["center_mm"]), "heading_deg": p["heading_deg"]}
                      for k, p in self._placed.items()}
            for move in moves:
                name = str(move.get("name", ""))
                if name not in placed:
                    raise SimConfigError(f"world {self.url}: apply: no part named {name!r} was placed")
                try:
                    du, dv, dh = (float(move.get(k, 0.0)) for k in ("du_mm", "dv_mm", "dheading_deg"))
                except (TypeError, ValueError):
                    raise SimConfigError(f"world {self.url}: apply: move of {name!r}: expected numbers du_mm, "
                                         f"dv_mm, dheading_deg") from None
                if not all(math.isfinite(x) for x in (du, dv, dh)):
                    raise SimConfigError(f"world {self.url}: apply: move of {name!r}: expected finite numbers")
                rng = self._rng(_FIX, self.attempt, int(round), _key(name))
                eu, ev = rng.normal(0.0, self.options["fix_mm"], 2)
                eh = rng.normal(0.0, self.options["fix_deg"])
                pose = placed[name]
                pose["center_mm"] = [pose["center_mm"][0] + du + float(eu), pose["center_mm"][1] + dv + float(ev)]
                pose["heading_deg"] = pose["heading_deg"] + dh + float(eh)
            self._placed = placed

    def placed(self) -> dict[str, dict]:
        """Where the parts ARE: ``{name: {"center_mm": [u, v], "heading_deg"}}``."""
        with self._lock:
            return {k: {"center_mm": list(p["center_mm"]), "heading_deg": p["heading_deg"]}
                    for k, p in self._placed.items()}

    def run_seed(self) -> int:
        """The seed of this attempt's run (deterministic in the world seed and the attempt)."""
        attempt = self.attempt if self.attempt is not None else 0
        return int(np.random.SeedSequence([self.seed, _RUN, attempt]).generate_state(1)[0])


def _pose(part: Mapping, url: str, what: str) -> tuple[str, tuple[float, float], float]:
    """A part's ``(name, (u, v), heading)``, checked."""
    try:
        name = str(part["name"])
        u, v = (float(x) for x in part["center_mm"])
        heading = float(part.get("heading_deg", 0.0))
    except (KeyError, TypeError, ValueError):
        raise SimConfigError(f"world {url}: {what}: expected parts as {{\"name\", \"center_mm\": [u, v], "
                             f"\"heading_deg\"}}, got {part!r}") from None
    if not all(math.isfinite(x) for x in (u, v, heading)):
        raise SimConfigError(f"world {url}: {what}: part {name!r}: expected finite center_mm and heading_deg")
    return name, (u, v), heading


def sim_world(url: str = "sim://world", **_: Any) -> SimulatedWorld:
    """The registry's factory: a new world, or the shared one when the URL has ``name=``."""
    return _SHARED.share(SimulatedWorld(url), url)


#: ``world_named(name)``: the shared world opened with ``name=...``, if any; ``forget_worlds()``: forget them all.
world_named, forget_worlds = _SHARED.named, _SHARED.forget


def parse_world_options(url: str) -> dict:
    """A ``sim://world?...`` URL's options with their defaults (SimConfigError naming a bad option)."""
    parts = urllib.parse.urlsplit(str(url).strip())
    if parts.scheme != "sim" or (parts.netloc or parts.path.lstrip("/")) != "world":
        raise SimConfigError(f"expected a sim://world URL, got {url!r}")
    values = dict(_DEFAULTS)
    query = {k: v[-1] for k, v in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items()}
    for key, text in query.items():
        if key not in _OPTIONS:
            raise SimConfigError(f"unknown sim world option {key!r}; known: {', '.join(sorted(_OPTIONS))}")
        values[key] = _option(key, text)
    return values


def _option(key: str, text: str) -> Any:
    if key == "name":
        if not text.strip():
            raise SimConfigError("sim world option name: expected a name, got ''")
        return text
    if key == "seed":
        if not text.isdigit() or int(text) > 2**32 - 1:
            raise SimConfigError(f"sim world option seed: expected a whole number from 0 to {2**32 - 1}, got {text!r}")
        return int(text)
    if key in _RANGES:
        low, high = _RANGES[key]
        try:
            pair = tuple(float(x) for x in text.split(","))
        except ValueError:
            pair = ()
        if len(pair) != 2 or not (low <= pair[0] <= pair[1] <= high):
            raise SimConfigError(f"sim world option {key}: expected lo,hi factors with {low:g} <= lo <= hi <= "
                                 f"{high:g} (e.g. {key}={','.join(f'{x:g}' for x in _DEFAULTS[key])}), got {text!r}")
        return pair
    return bounded_number("world", key, text, *_NUMBERS[key])
