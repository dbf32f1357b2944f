"""Batch calls name the infeasible row and keep the error's type and attributes (constraint, margin)."""

from __future__ import annotations

import pytest

from design.errors import ConstraintViolation, DesignError
from design.machines import get_machine

#: A spirograph design whose pen is outside the rolling gear: constraint pen_inside_gear, margin 3 - 4.5.
BAD = {"r_f": 7, "r_r": 3, "d": 4.5}


@pytest.mark.parametrize(
    "call",
    [
        lambda m, rows: m.sample_many(rows, n=16),
        lambda m, rows: m.curve_many(rows, [0.0, 1.0]),
        lambda m, rows: m.period_many(rows),
    ],
    ids=["sample_many", "curve_many", "period_many"],
)
def test_constraint_violation_of_a_row_keeps_constraint_and_margin(call):
    machine = get_machine("spirograph")
    with pytest.raises(ConstraintViolation) as single:
        machine.validate(BAD)
    with pytest.raises(ConstraintViolation) as batch:
        call(machine, [machine.defaults(), BAD])
    assert str(batch.value) == f"row 1: {single.value}"
    assert batch.value.constraint == "pen_inside_gear"
    assert batch.value.margin == pytest.approx(-1.5)


class _LimitError(DesignError):
    """An error whose constructor takes more than a message (as a plug-in machine's may)."""

    def __init__(self, what: str, limit: float) -> None:
        super().__init__(f"{what} is over {limit:g}")
        self.what = what
        self.limit = limit


def test_an_error_that_takes_more_than_a_message_is_not_rebuilt():
    machine = get_machine("spirograph")

    class Picky(type(machine)):
        def validate(self, params=None):
            raise _LimitError("d", 4.0)

    with pytest.raises(_LimitError) as info:
        Picky().sample_many([machine.defaults(), BAD], n=16)
    assert str(info.value) == "row 1: d is over 4"
    assert (info.value.what, info.value.limit) == ("d", 4.0)
