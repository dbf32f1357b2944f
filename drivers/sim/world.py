"""The simulated physical world (``sim://world``): a maker who places parts with human error, and physics that
differ from what the scenario assumes.

It is the last twin the station needs to run its whole loop without a table: the station hands it plain data (the
parts' poses as the guide draws them, the moves a check asks for, the scenario's material values) and asks where
the parts really are and which physics really hold. ``drivers`` never imports ``design``: running the contraption
under the hidden physics is the station's job (:mod:`station.services.world`).

URL options (``sim://world?seed=3&place_mm=2&ruler_mm=1.5&jig_mm=0.2&fix_mm=0.5``)
----------------------------------------------------------------------------------------------
``seed`` (whole number, default 0: everything random in this world follows from it), ``friction`` (``lo,hi``: the
range of the factor on every friction, rolling and spinning friction, default 0.7,1.3), ``restitution`` (the
half-width of the uniform shift of every restitution, default 0.15), ``damping`` (``lo,hi``: the range of the factor
on linear and angular damping, default 0.5,2) and ``name`` (share one world between the opens of that name, as
``sim://camera?name=`` does). The maker's hands, one error model per way the guide says to set a parameter (its
``set_with``), each a standard deviation per axis, in mm or degrees:

- ``place_mm`` / ``place_deg`` (``sheet``, default 2 and 2): a part laid by eye on its outline on the sheet; 2 mm is
  about the width of a drawn outline plus the part's own slack round it, 2 deg the turn a 60 mm edge shows as 2 mm.
- ``highlight`` (default 0.5): the factor on the ``sheet`` error when the projector highlights the part (or the jig)
  being placed: the light on the part itself halves what the eye must judge.
- ``ruler_mm`` / ``ruler_deg`` (``ruler``, default 1.5 and 2): a number read off and set with a steel rule or a
  protractor, the part held there while it is fixed: a rule's 0.5 mm graduation, its parallax and the part's sag
  make 1.5 mm; a protractor's 1 deg marks and the hand that holds the part make 2 deg.
- ``jig_mm`` / ``jig_deg`` (``jig``, default 0.2 and 0.2): the part seated on its laser-cut jig: the laser's
  repeatability and kerf variation (about 0.1 mm) plus the seating of the part on the edge (about 0.1 mm); 0.2 mm
  over a support of about 60 mm is 0.2 deg. The jig itself is laid by eye over its footprint on the sheet (the
  ``sheet`` error, highlighted or not), and that error carries into the in-plane place of every part it sets.
- ``fix_mm`` / ``fix_deg`` (``check``, default 0.5 and 0.5): a part moved as a camera check's instruction says
  ("move it 2.1 mm right"): a move of a known size is half a millimetre out, the check's own resolution.
- A parameter the guide does not state at all: the maker guesses it, uniformly over its range.

An unknown option or a bad value is one :class:`drivers.errors.SimConfigError` line naming it.

What the maker is told
----------------------
The world knows only what the guide tells the maker, as plain data: each part's drawn pose (``center_mm``,
``heading_deg``), its ``parameters`` as the guide manifest states them (``name``, ``value``, ``unit``, ``role``,
``set_with``), the jigs (``id``, ``part``, ``parameters``) and, to guess what no guide states, the range of every
design parameter. In-plane parameters (role ``u``, ``v``, ``turn``) follow the part's pose as placed (the camera sees
it); every other parameter is set on its own (:meth:`SimulatedWorld.settings`).

Seeds
-----
Every random draw has its own stream from :class:`numpy.random.SeedSequence` of the world seed and what it is for
(a hidden value: its name; a placement: the attempt and the part's name; a jig's placement: the attempt and the
jig's id; a parameter set on its own: the attempt and the parameter's name; a guess: the same, on another stream; a
correction: the attempt, the round and the part's name; a run: the attempt), so a draw never depends on the order of
the others: an attempt replayed after an interruption places every part exactly as it did.
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

__all__ = ["SimulatedWorld", "forget_worlds", "maker_sigma", "parse_world_options", "sim_world", "world_named"]

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
    "ruler_mm": (0.0, 100.0, "a standard deviation in mm from 0 to 100"),
    "ruler_deg": (0.0, 90.0, "a standard deviation in degrees from 0 to 90"),
    "jig_mm": (0.0, 100.0, "a standard deviation in mm from 0 to 100"),
    "jig_deg": (0.0, 90.0, "a standard deviation in degrees from 0 to 90"),
    "highlight": (0.0, 1.0, "a factor from 0 to 1"),
    "restitution": (0.0, 1.0, "a half-width from 0 to 1"),
}
_RANGES = {"friction": (0.0, 10.0), "damping": (0.0, 100.0)}  # option: (lowest, highest) of lo,hi
_OPTIONS = ("seed", "name", *_NUMBERS, *_RANGES)
_DEFAULTS: dict[str, Any] = {"seed": 0, "name": "", "place_mm": 2.0, "place_deg": 2.0, "fix_mm": 0.5,
                             "fix_deg": 0.5, "ruler_mm": 1.5, "ruler_deg": 2.0, "jig_mm": 0.2, "jig_deg": 0.2,
                             "highlight": 0.5, "friction": (0.7, 1.3), "restitution": 0.15, "damping": (0.5, 2.0)}
#: How a guide may tell the maker to set a parameter (the guide manifest's ``set_with``).
SET_WITH = ("sheet", "ruler", "jig", "check")
#: The roles of a parameter that moves its part along the guide plane (the part's pose carries them).
IN_PLANE_ROLES = ("u", "v", "turn")
#: What the world's behaviour is (runs of the loop keyed by it are not mixed with another world's).
WORLD_REVISION = 2

# What each stream of random numbers is for (the first word of its SeedSequence entropy after the seed).
_PHYSICS, _PLACE, _FIX, _RUN, _SET, _GUESS, _JIG = 1, 2, 3, 4, 5, 6, 7

_SHARED: SharedTwins[SimulatedWorld] = SharedTwins("world")


def maker_sigma(how: str, highlighted: bool = False, options: Mapping[str, Any] | None = None) -> tuple[float, float]:
    """The maker's error (standard deviations in mm and degrees) when setting something ``how`` (a guide manifest's
    ``set_with``): with a ruler, seated on a jig, else by eye on the sheet (a ``check`` parameter too, before the
    check's first instruction), scaled by ``highlight`` when the projector highlights the part. ``options``: a
    world's URL options (:func:`parse_world_options`); default the defaults, the maker the station assumes when it
    predicts."""
    o = _DEFAULTS if options is None else options
    if how == "ruler":
        return o["ruler_mm"], o["ruler_deg"]
    if how == "jig":
        return o["jig_mm"], o["jig_deg"]
    factor = o["highlight"] if highlighted else 1.0
    return o["place_mm"] * factor, o["place_deg"] * factor


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
        self._settings: dict[str, dict] = {}
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

    def _sigma(self, how: str, highlighted: bool) -> tuple[float, float]:
        """The maker's error (mm, deg) when setting something ``how`` in this world (:func:`maker_sigma`)."""
        return maker_sigma(how, highlighted, self.options)

    def place(self, parts: Sequence[Mapping], *, attempt: int, highlighted: bool = False,
              jigs: Sequence[Mapping] = (), ranges: Mapping[str, Sequence] | None = None) -> None:
        """Place every part anew for ``attempt`` as the guide tells the maker, each with the maker's error.

        Parameters
        ----------
        parts : sequence of mappings
            ``[{"name", "center_mm": [u, v], "heading_deg", "parameters": [...]}]`` as the guide draws them; a
            part's ``parameters`` (optional) are the guide manifest's: ``{"name", "value", "unit", "role",
            "set_with"}``.
        attempt : int
            The attempt (0, 1, ...): with the part's name and the world seed, it seeds the error.
        highlighted : bool
            The projector highlights each part (and jig) as it is placed: the by-eye error is scaled by
            ``highlight``.
        jigs : sequence of mappings
            The guide's jigs, ``[{"id", "part", "parameters"}]``: each is laid by eye over its footprint (the
            ``sheet`` error), its part seated on it (the ``jig`` error): the part's pose is the jig's plus the
            seating.
        ranges : mapping, optional
            ``{name: [lower, upper, unit]}`` of every design parameter (unit ``"mm"`` or ``"deg"``): one no part
            states is guessed uniformly over its range.

        Notes
        -----
        A part's pose error follows how its in-plane parameters are set: on a jig, the jig's placement plus the
        seating; with a ruler, the ruler's error; else by eye (``sheet``, and ``check`` before the check's
        instructions). Every parameter stated is also set on its own, with the error of its ``set_with``
        (:meth:`settings`): the station takes the out-of-plane ones from there, the in-plane ones from the pose.
        """
        by_part: dict[str, Mapping] = {}
        for jig in jigs:
            by_part.setdefault(str(_field(jig, "part", self.url, "jig")), jig)
        placed, settings = {}, {}
        for part in parts:
            name, (u, v), heading = _pose(part, self.url, "place")
            stated = _parameters(part, self.url)
            rng = self._rng(_PLACE, int(attempt), _key(name))
            in_plane = {p["set_with"] for p in stated if p["role"] in IN_PLANE_ROLES}
            jig = by_part.get(name)
            if jig is not None:  # laid by eye over its footprint; the part seated on it
                jig_rng = self._rng(_JIG, int(attempt), _key(str(jig.get("id", name))))
                mm, deg = self._sigma("sheet", highlighted)
                du, dv = jig_rng.normal(0.0, mm, 2)
                dh = jig_rng.normal(0.0, deg)
                mm, deg = self._sigma("jig", highlighted)
                du, dv = np.add([du, dv], rng.normal(0.0, mm, 2))
                dh = dh + rng.normal(0.0, deg)
            else:
                mm, deg = self._sigma("ruler" if "ruler" in in_plane else "sheet", highlighted)
                du, dv = rng.normal(0.0, mm, 2)
                dh = rng.normal(0.0, deg)
            placed[name] = {"center_mm": [u + float(du), v + float(dv)], "heading_deg": heading + float(dh)}
            for parameter in stated:
                if parameter["name"] in settings:
                    continue  # stated by several parts (an Empty frame's): set once
                mm, deg = self._sigma(parameter["set_with"], highlighted)
                sigma = deg if parameter["unit"] == "deg" else mm
                error = self._rng(_SET, int(attempt), _key(parameter["name"])).normal(0.0, sigma)
                settings[parameter["name"]] = {"value": parameter["value"] + float(error), "unit": parameter["unit"],
                                               "set_with": parameter["set_with"], "role": parameter["role"]}
        for name, bounds in (ranges or {}).items():
            if name in settings:
                continue
            lower, upper, unit = _range(name, bounds, self.url)
            guess = lower + (upper - lower) * float(self._rng(_GUESS, int(attempt), _key(str(name))).uniform())
            settings[str(name)] = {"value": guess, "unit": unit, "set_with": "guess", "role": None}
        with self._lock:
            self.attempt = int(attempt)
            self._placed = placed
            self._settings = settings

    def apply(self, moves: Sequence[Mapping], *, round: int) -> None:  # noqa: A002 (the contract's name)
        """Move parts as a check's instructions say, with the maker's (smaller) error.

        Parameters
        ----------
        moves : sequence of mappings
            ``[{"name", "du_mm", "dv_mm", "dheading_deg"}]``: designed minus measured, what the instruction says;
            a move may also carry ``"parameters": {name: change}`` (in the parameter's unit) for parameters a check
            measures off the plane (a height, a tilt), each set with the same correcting error.
        round : int
            The check round (1, 2, ...): with the attempt, the part's name and the world seed, it seeds the error.
        """
        with self._lock:
            if self.attempt is None:
                raise SimConfigError(f"world {self.url}: apply: no parts placed yet (place() them first)")
            placed = {k: {"center_mm": list(p["center_mm"]), "heading_deg": p["heading_deg"]}
                      for k, p in self._placed.items()}
            settings = {k: dict(v) for k, v in self._settings.items()}
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
                changes = move.get("parameters") or {}
                if not isinstance(changes, Mapping):
                    raise SimConfigError(f"world {self.url}: apply: move of {name!r}: expected parameters as "
                                         f"{{name: change}}, got {changes!r:.60}")
                for parameter, change in changes.items():
                    setting = settings.get(str(parameter))
                    try:
                        change = float(change)
                    except (TypeError, ValueError):
                        change = math.nan
                    if setting is None or not math.isfinite(change):
                        raise SimConfigError(f"world {self.url}: apply: move of {name!r}: parameters[{parameter!r}]"
                                             f": expected a finite change of a parameter set at placing")
                    sigma = self.options["fix_deg" if setting["unit"] == "deg" else "fix_mm"]
                    error = self._rng(_FIX, self.attempt, int(round), _key(str(parameter))).normal(0.0, sigma)
                    setting["value"] = setting["value"] + change + float(error)
            self._placed = placed
            self._settings = settings

    def placed(self) -> dict[str, dict]:
        """Where the parts ARE: ``{name: {"center_mm": [u, v], "heading_deg"}}``."""
        with self._lock:
            return {k: {"center_mm": list(p["center_mm"]), "heading_deg": p["heading_deg"]}
                    for k, p in self._placed.items()}

    def settings(self) -> dict[str, dict]:
        """Every parameter as the maker set it: ``{name: {"value", "unit", "set_with", "role"}}`` (``set_with``
        ``"guess"`` for one the guide did not state; ``role`` None then)."""
        with self._lock:
            return {k: dict(v) for k, v in self._settings.items()}

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


def _field(data: Mapping, key: str, url: str, what: str) -> Any:
    if not isinstance(data, Mapping) or key not in data:
        raise SimConfigError(f"world {url}: place: expected each {what} with {key!r}, got {data!r:.80}")
    return data[key]


def _parameters(part: Mapping, url: str) -> list[dict]:
    """A part's stated parameters, checked: ``[{"name", "value", "unit", "role", "set_with"}]``."""
    entries = part.get("parameters") or []
    result = []
    for entry in entries if isinstance(entries, list) else [entries]:
        try:
            name, unit, role, how = (str(entry[k]) for k in ("name", "unit", "role", "set_with"))
            value = float(entry["value"])
        except (KeyError, TypeError, ValueError):
            name = unit = how = ""
            value = math.nan
        if not name or unit not in ("mm", "deg") or how not in SET_WITH or not math.isfinite(value):
            raise SimConfigError(f"world {url}: place: part {part.get('name')!r}: expected parameters as "
                                 f"{{\"name\", \"value\": a finite number, \"unit\": \"mm\" or \"deg\", \"role\", "
                                 f"\"set_with\": one of {', '.join(SET_WITH)}}}, got {entry!r:.80}")
        result.append({"name": name, "value": value, "unit": unit, "role": role, "set_with": how})
    return result


def _range(name: str, bounds: Sequence, url: str) -> tuple[float, float, str]:
    try:
        lower, upper, unit = float(bounds[0]), float(bounds[1]), str(bounds[2])
    except (IndexError, TypeError, ValueError):
        lower = upper = math.nan
        unit = ""
    if unit not in ("mm", "deg") or not (math.isfinite(lower) and math.isfinite(upper) and lower <= upper):
        raise SimConfigError(f"world {url}: place: ranges[{name!r}]: expected [lower, upper, \"mm\" or \"deg\"] "
                             f"with lower <= upper, got {bounds!r:.60}")
    return lower, upper, unit


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
