"""GRBL 1.1 driver: port opening by URL, discovery, character-counting streaming, a real-time path, message parsing,
job control with pre-flight and laser safety.

>>> from drivers.grbl import GrblConnection, Job, JobRunner
>>> with GrblConnection("sim://grbl?profile=plotter&time_scale=0.01") as conn:   # doctest: +SKIP
...     result = JobRunner(conn, Job.from_file("job.gcode")).run()
"""

from drivers.grbl.connection import GrblConnection, LineResult, StreamStopped, open_port
from drivers.grbl.discovery import PortInfo, list_ports, probe
from drivers.grbl.job import JobRunner
from drivers.grbl.job_types import Job, JobProgress, JobResult, frame_lines
from drivers.grbl.protocol import ALARM_CODES, ERROR_CODES, StatusReport, parse_line

__all__ = [
    "ALARM_CODES",
    "ERROR_CODES",
    "GrblConnection",
    "Job",
    "JobProgress",
    "JobResult",
    "JobRunner",
    "LineResult",
    "PortInfo",
    "StatusReport",
    "StreamStopped",
    "frame_lines",
    "list_ports",
    "open_port",
    "parse_line",
    "probe",
]
