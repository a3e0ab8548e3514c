"""The local web page: live height view, touches and trails, drawing pad, pinch zoom, calibration.

Needs the ``web`` extra (aiohttp). :class:`~depthtouch.web.server.WebServer` serves the page and
the WebSocket stream from a background thread; :func:`~depthtouch.web.serve.run_serve` is the
``depthtouch serve`` command; :func:`~depthtouch.web.latency.measure_ws_latency` measures the
event latency for benchmarks. Import the submodules directly; this package imports nothing.
"""
