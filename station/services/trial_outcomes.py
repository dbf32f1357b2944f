"""What a maker says of each event of a trial, and what it implies: the outcome words and the rules that fill in the
outcomes not said (an event after one that did not happen was not reached...), for a face that asks event by event
(the Trials screen's table). The rules are :mod:`station.trialformat`'s, the same the trial log checks.
"""

from __future__ import annotations

from station.trialformat import NO, NOT_REACHED, OUTCOMES, YES, goal_reached, resolve_outcomes

__all__ = ["NO", "NOT_REACHED", "OUTCOMES", "YES", "goal_reached", "resolve_outcomes"]
