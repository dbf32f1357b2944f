"""What a maker reads about a layout's chance of working: one headline, the same words everywhere.

The headline (CLI, TUI, check overlays, sheets, the browser) is the **physical success on the table**: the share
of simulations of the layout placed as the maker places it (the guide's or the check's placement error) under the
station's physics that succeed, with its 95 % interval and the attempts to expect (1/p). The success model's score
(the optimizer's fitted PSP) is a *detail*: it ranks layouts near the optimizer's samples and can be far off
elsewhere, so it is shown only as the model's own score, and when it and the simulations disagree the maker is told
so and what to do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from types import SimpleNamespace

from station.errors import station_errors

__all__ = ["DISAGREE_HIGH", "DISAGREE_LOW", "attempts_words", "disagreement", "layout_headline",
           "left_out_words", "model_detail", "prediction_from_json", "success_headline"]

#: The model and the simulations disagree when one says under DISAGREE_LOW and the other over DISAGREE_HIGH: a
#: model that far off at the layout is no guide to its tolerances or to its success.
DISAGREE_LOW, DISAGREE_HIGH = 0.2, 0.8


@station_errors
def attempts_words(attempts: float, interval: tuple[float, float]) -> str:
    """``expect 1.5 attempts (1.2-1.8)``; ``expect 3.0 attempts (2.1 or more)`` when the interval reaches a zero
    success; ``no success expected (at best 1 in 13.5 attempts)`` when none succeeded."""
    low, high = interval
    if math.isinf(attempts):
        return "no success expected" + ("" if math.isinf(low) else f" (at best 1 in {low:.1f} attempts)")
    spread = f"{low:.1f} or more" if math.isinf(high) else f"{low:.1f}-{high:.1f}"
    return f"expect {attempts:.1f} attempts ({spread})"


@station_errors
def success_headline(prediction, *, when: str = "") -> str:
    """``physical success on the table 0.69 (95 %: 0.55-0.80): expect 1.5 attempts (1.2-1.8)``, then ``when``
    (``"as placed, 48 simulations"``) in brackets when given.

    ``prediction`` is a :class:`calibration.sim_predict.PhysicalPrediction` (or anything with its ``probability``,
    ``interval``, ``attempts`` and ``attempts_interval``)."""
    low, high = prediction.interval
    text = (f"physical success on the table {prediction.probability:.2f} (95 %: {low:.2f}-{high:.2f}): "
            f"{attempts_words(prediction.attempts, prediction.attempts_interval)}")
    return f"{text} ({when})" if when else text


@station_errors
def model_detail(as_built: float | None, as_designed: float | None = None, *, placed: bool = True) -> str | None:
    """``detail: the success model's own score 0.02 as placed (0.02 as designed)``; None without a model score."""
    if as_built is None:
        return None
    where = " as placed" if placed else ""
    designed = (f" ({as_designed:.2f} as designed)" if as_designed is not None and placed
                and round(as_designed, 2) != round(as_built, 2) else "")
    return f"detail: the success model's own score {as_built:.2f}{where}{designed}"


@station_errors
def disagreement(model: float | None, simulated: float | None, samples: int | None = None) -> str | None:
    """The plain words when the success model and the simulations disagree about a layout (one under
    :data:`DISAGREE_LOW`, the other over :data:`DISAGREE_HIGH`), with what to do; None when they agree or either is
    unknown."""
    if model is None or simulated is None:
        return None
    low, high = sorted((model, simulated))
    if not (low < DISAGREE_LOW and high > DISAGREE_HIGH):
        return None
    over = f" of {samples}" if samples else ""
    return (f"the success model and the simulations disagree about this layout (model {model:.2f}, simulations "
            f"{simulated:.2f}{over}): the model is weak here, so trust the simulations; its tolerances are "
            "verified by simulation (`station tolerances LAYOUT --verify 40`), and `station optimize` with a larger "
            "--budget fits a better model")


@station_errors
def left_out_words(parts: Sequence[str]) -> str | None:
    """What the predictions leave out: parts the check found misplaced that no design parameter places (the
    simulations put them where the design does); None when there are none."""
    if not parts:
        return None
    names = ", ".join(f"`{p}`" for p in parts)
    return (f"the predictions leave out where {names} stand{'s' if len(parts) == 1 else ''} (no design parameter "
            "places it: simulated where the guide puts it): move it as the check says before you run")


@station_errors
def prediction_from_json(data) -> SimpleNamespace | None:
    """A ``physical_success`` table (LAYOUT.json's, CHECK.json's: ``probability``, ``interval``,
    ``expected_attempts``, ``attempts_interval``, ``samples``) as the object :func:`success_headline` reads; None
    when it is missing or not such a table (JSON's null attempts are infinite)."""
    if not isinstance(data, Mapping):
        return None
    try:
        probability = float(data["probability"])
        interval = tuple(float(v) for v in data["interval"])
        attempts = _infinite(data.get("expected_attempts"))
        attempts_interval = tuple(_infinite(v) for v in data.get("attempts_interval") or (None, None))
        samples = int(data.get("samples") or 0)
    except (KeyError, TypeError, ValueError):
        return None
    if len(interval) != 2 or len(attempts_interval) != 2:
        return None
    return SimpleNamespace(probability=probability, interval=interval, attempts=attempts,
                           attempts_interval=attempts_interval, samples=samples)


def _infinite(value) -> float:
    return math.inf if value is None else float(value)


@station_errors
def layout_headline(data, when: str = "placed by the guide") -> str | None:
    """The headline of a LAYOUT.json's ``physical_success`` (written by ``station optimize``), None without one."""
    prediction = prediction_from_json(data.get("physical_success") if isinstance(data, Mapping) else None)
    if prediction is None:
        return None
    return success_headline(prediction, when=f"{when}, {prediction.samples} simulations")
