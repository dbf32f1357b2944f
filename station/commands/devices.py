"""``station devices``: the station's configured devices (``station.toml``) and what a brief probe says of each."""

from __future__ import annotations

import sys

from station.cli_util import emit_json
from station.config import config_location, load_config, write_default_config
from station.devices import driver_name, probe_devices

#: The ``--json`` contract, quoted in the help text; keep it stable (add keys, never rename or drop one).
JSON_SHAPE = ('{"config": PATH or null, "devices": [{"name": ..., "kind": ..., "url": ..., "simulated": true|false, '
              '"driver": NAME or null, "state": ...}]}')


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "devices",
        help="the station's devices (station.toml) and their state",
        description="List the station's devices in the order of its config file: name, kind (plotter, laser, "
        "camera, projector), simulated or real, URL, driver, and the state a brief probe finds (a GRBL machine's "
        "port is opened and asked its status with '?', no soft reset: 'connected: Grbl 1.1h, Idle', "
        "'not connected: no such port'; a projector 'open: 1920x1080 (display 1 of 2, x11)' or 'not available: "
        "...', asked without making a window; a camera 'open: 1920x1080' once it gave a frame, or 'not available: "
        "...'). Probes run side by side and "
        "answer within about a second (a device's options.timeout, if longer; a real projector within 4 s, a real "
        "camera within 2 s). "
        "The devices come from "
        "CHAOS_STATION_CONFIG if set, else station.toml in the data folder (CHAOS_STATION_HOME), else the "
        "built-in default: every device simulated (--init writes it as a commented station.toml to edit). "
        "An Arduino-based controller resets when its port is opened: do not probe a machine another program is "
        f"driving (--no-probe). --json prints {JSON_SHAPE}; config is null when the built-in default is used, "
        "driver null when the kind has no driver yet.",
        epilog="examples:\n  station devices\n  station devices --json --no-probe\n  station devices --init",
    )
    parser.add_argument("--json", action="store_true", help=f"print the devices as JSON: {JSON_SHAPE}")
    parser.add_argument("--no-probe", action="store_true",
                        help="do not open the devices' ports; their state is 'not probed' ('no driver yet' stays)")
    parser.add_argument("--init", action="store_true",
                        help="first write the built-in default to the config file where none exists (never over "
                        "an existing file), then list")
    parser.set_defaults(func=run_devices)


def run_devices(args) -> int:
    if args.init:
        written = write_default_config()
        print(f"wrote {written} (every device simulated; edit it to name your devices)",
              file=sys.stderr if args.json else sys.stdout)
    config = load_config()
    devices = config.devices
    drivers = [driver_name(d) for d in devices]
    if args.no_probe:  # what needs no port is known all the same
        states = ["not probed" if driver else "no driver yet" for driver in drivers]
    else:
        states = probe_devices(devices)
    rows = [{"name": d.name, "kind": d.kind, "url": d.url, "simulated": d.simulated, "driver": driver,
             "state": state} for d, driver, state in zip(devices, drivers, states)]
    if args.json:
        emit_json({"config": str(config.path) if config.path is not None else None, "devices": rows})
        return 0
    if config.path is not None:
        print(f"config: {config.path}")
    else:
        print(f"config: none, every device simulated (write {config_location()[0]} or run "
              "`station devices --init` to name your devices)")
    if not rows:
        print("no devices configured")
        return 0
    table = [("NAME", "KIND", "MODE", "URL", "DRIVER", "STATE")] + [
        (r["name"], r["kind"], "simulated" if r["simulated"] else "real", r["url"], r["driver"] or "none yet",
         r["state"]) for r in rows]
    widths = [max(len(row[column]) for row in table) for column in range(5)]
    for row in table:
        print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)) + "  " + row[5])
    return 0
