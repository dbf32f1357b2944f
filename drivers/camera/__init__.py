"""Cameras: the real one on OpenCV's ``VideoCapture`` (:mod:`drivers.camera.opencv`: an index, ``/dev/video*``, a
stream URL or a video file) and, for what both follow, :class:`drivers.devices.Camera`. The simulated twin is
:mod:`drivers.sim.camera` (``sim://camera``)."""

from drivers.camera.opencv import FRAME_TIMEOUT, OpenCVCamera, opencv_camera

__all__ = ["FRAME_TIMEOUT", "OpenCVCamera", "opencv_camera"]
