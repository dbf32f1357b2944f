"""``station predict``: physical success probability and expected attempts of a layout (thesis 5.2.3)."""

from __future__ import annotations

import math
import sys

from station.cli_util import emit_json, flag_error
from station.commands.contraption import report_layout
from station.commands.robust import _where, add_command, add_scenario_and_layout, add_workers, command
from station.errors import ServiceError


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "predict", run_predict,
        help="physical success probability and expected attempts of a layout (as designed or as built)",
        description="Estimate how likely one physical attempt of a layout is to succeed, and how many attempts to "
        "expect (1/p), by simulating it --samples times with the placement error of the check (its residual "
        "error; else 1 mm and 1 degree) and, with --physics, the calibrated material values (drawn from their "
        "intervals). --as-built CHECK.json simulates the layout the check measured instead of the designed one. "
        "The interval of the probability is Wilson's 95 % interval; that of the attempts is its inverse.",
        examples=["simple layout.json --physics simple-physics.toml",
                  "simple layout.json --as-built check.json --samples 100 --json"],
    )
    add_scenario_and_layout(parser)
    parser.add_argument("--as-built", metavar="CHECK.json", default=None,
                        help="the check of this layout (`station check --out`): simulate what it measured")
    parser.add_argument("--samples", type=int, default=200, metavar="N", help="simulations (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the placement errors (default 0)")
    add_workers(parser)  # --workers, --scheduler and --physics
    parser.add_argument("--json", action="store_true", help="print the prediction as JSON")


def _number(value: float) -> str:
    return "unbounded" if math.isinf(value) else f"{value:.2f}"


@command
def run_predict(args) -> int:
    from station.services.predict import predict  # heavy: design.contraption.simulation, pybullet, scipy, shapely

    try:
        prediction = predict(args.scenario, args.layout, physics=args.physics, as_built=args.as_built,
                             samples=args.samples, seed=args.seed, **_where(args))
    except ServiceError as error:
        raise flag_error(error, {"as_built": "--as-built"}) from None
    args.bar.close()
    report_layout(prediction.layout, sys.stderr)
    if args.json:
        emit_json(prediction.to_json())
        return 0
    result = prediction.result
    lo, hi = result.interval
    a_lo, a_hi = result.attempts_interval
    physics = f"profile {prediction.profile!r}" if prediction.profile else "the scenario's own"
    which = "as built (from the check)" if prediction.as_built else "as designed"
    print(f"{prediction.scenario.name}: layout {which}; physics: {physics}; placement error "
          f"{result.position_sigma_mm:.2g} mm / {result.angle_sigma_deg:.2g} deg")
    print(f"  success probability  {result.probability:.3f}  (95 % {lo:.3f} to {hi:.3f}; {result.successes} of "
          f"{result.samples} simulations)")
    print(f"  expected attempts    {_number(result.attempts)}  (95 % {_number(a_lo)} to {_number(a_hi)})")
    print("  events:")
    for name, p in result.events.items():
        print(f"    {name:24s} {p:.3f}")
    return 0
