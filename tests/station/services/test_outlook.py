"""One success number in the maker's words: the physical success on the table first, the model's score a detail."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from station.services.outlook import attempts_words, disagreement, left_out_words, model_detail, success_headline


def _prediction(p, interval, samples=48):
    inverse = lambda v: math.inf if v <= 0 else 1 / v  # noqa: E731
    return SimpleNamespace(probability=p, interval=interval, attempts=inverse(p),
                           attempts_interval=(inverse(interval[1]), inverse(interval[0])), samples=samples)


@pytest.mark.parametrize(("p", "interval", "words"), [
    (0.69, (0.55, 0.80), "physical success on the table 0.69 (95 %: 0.55-0.80): expect 1.4 attempts (1.2-1.8)"),
    (1.0, (0.93, 1.0), "physical success on the table 1.00 (95 %: 0.93-1.00): expect 1.0 attempts (1.0-1.1)"),
    (0.1, (0.0, 0.3), "physical success on the table 0.10 (95 %: 0.00-0.30): expect 10.0 attempts (3.3 or more)"),
    (0.0, (0.0, 0.074), "physical success on the table 0.00 (95 %: 0.00-0.07): no success expected (at best 1 in "
                        "13.5 attempts)"),
])
def test_the_headline_is_the_physical_success_with_its_interval_and_the_attempts(p, interval, words):
    assert success_headline(_prediction(p, interval)) == words
    assert success_headline(_prediction(p, interval), when="as placed, 48 simulations").endswith(
        "(as placed, 48 simulations)")


def test_attempts_words_never_print_infinity():
    assert "inf" not in attempts_words(math.inf, (math.inf, math.inf))
    assert attempts_words(math.inf, (math.inf, math.inf)) == "no success expected"


@pytest.mark.parametrize(("model", "simulated", "disagree"), [
    (0.017, 1.0, True), (0.02, 0.81, True), (0.9, 0.1, True),  # one under 0.2, the other over 0.8
    (0.2, 0.95, False), (0.5, 1.0, False), (0.85, 0.25, False), (0.7, 0.9, False),
    (None, 1.0, False), (0.01, None, False),
])
def test_the_model_and_the_simulations_disagree_only_when_far_apart(model, simulated, disagree):
    words = disagreement(model, simulated, 48)
    assert (words is not None) == disagree
    if disagree:
        assert f"model {model:.2f}" in words and "--verify" in words and "--budget" in words


def test_the_model_score_is_a_detail_named_as_such():
    assert model_detail(None) is None
    assert model_detail(0.02, 0.02) == "detail: the success model's own score 0.02 as placed"
    assert model_detail(0.40, 0.89) == "detail: the success model's own score 0.40 as placed (0.89 as designed)"


def test_what_the_predictions_leave_out_is_named():
    assert left_out_words(()) is None
    assert "`low_plank` stands" in left_out_words(["low_plank"])
