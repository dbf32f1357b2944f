"""The station's one family of errors: the packages' errors become station errors where a service is entered."""

from __future__ import annotations

import pickle

import pytest

from calibration.errors import CalibrationError
from common.progress import Cancelled
from design.errors import ConstraintViolation, DesignError, FileFormatError
from drivers.errors import DriverError, PortError
from drivers.gcode import GcodeError
from station.errors import USER_ERRORS, ServiceError, StationError, as_station_error, station_errors
from vision.errors import VisionError


@pytest.mark.parametrize("error", [
    FileFormatError("a.json: not valid JSON (Expecting value at line 1 column 1); expected a design"),
    ConstraintViolation("d must be < r_r", constraint="d<r_r", margin=-0.5),
    PortError("port /dev/ttyUSB0: no such port"),
    GcodeError("line 3: G99 is not a G-code GRBL runs"),  # a DriverError and a ValueError
    CalibrationError("images: 2 boards found, expected at least 5"),
    VisionError("tag 900: expected an id in 0..586"),
])
def test_a_package_error_becomes_a_station_error_with_its_message_class_and_fields(error):
    translated = as_station_error(error)
    assert isinstance(translated, StationError) and isinstance(translated, USER_ERRORS)
    assert isinstance(translated, type(error))  # code that catches the package's own error still catches it
    assert str(translated) == str(error) and type(translated).__name__ == type(error).__name__
    assert vars(translated) == vars(error)


def test_other_errors_pass_as_they_are():
    for error in (ServiceError("top must be >= 1, got 0", field="top"), Cancelled("stopped"), KeyError("x"),
                  OSError(2, "No such file or directory")):
        assert as_station_error(error) is error


def test_an_entry_point_translates_what_it_raises_and_what_its_generator_raises():
    @station_errors
    def read(path):
        raise FileFormatError(f"{path}: expected a design")

    @station_errors
    def lines():
        yield "G0 X1"
        raise PortError("port gone")

    with pytest.raises(StationError, match="^x.json: expected a design$") as caught:
        read("x.json")
    assert isinstance(caught.value, DesignError) and isinstance(caught.value.__cause__, FileFormatError)
    produced = lines()
    assert next(produced) == "G0 X1"
    with pytest.raises(StationError, match="port gone") as caught:
        next(produced)
    assert isinstance(caught.value, DriverError)


def test_a_class_entry_translates_its_construction_methods_and_properties():
    @station_errors
    class Session:
        def __init__(self, bad: bool) -> None:
            if bad:
                raise DesignError("design: bad")

        def move(self):
            raise DesignError("move: bad")

        @property
        def state(self):
            raise DesignError("state: bad")

        @staticmethod
        def parse(text):
            raise DesignError(f"{text}: bad")

    for call in (lambda: Session(True), lambda: Session(False).move(), lambda: Session(False).state,
                 lambda: Session.parse("x")):
        with pytest.raises(StationError):
            call()


def test_a_translated_error_pickles_as_itself():
    # a worker process or a log may pickle it: it comes back translated, with its message and fields
    error = as_station_error(ConstraintViolation("d must be < r_r", constraint="d<r_r", margin=-0.5))
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error) and str(back) == str(error) and back.margin == -0.5
    assert type(as_station_error(DesignError("a"))) is type(as_station_error(DesignError("b")))  # made once


def test_a_service_raises_a_station_error_for_a_missing_scenario():
    from station.services.contraption import open_scenario

    with pytest.raises(StationError, match="scenario 'missing.toml': no such file"):
        open_scenario("missing.toml")
