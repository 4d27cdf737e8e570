"""The control loop in a process of its own: the engine's surface over a pipe and shared memory.

:mod:`~tracker.loop_process.proxy` (the service's side), :mod:`~tracker.loop_process.child` (the
loop's process), :mod:`~tracker.loop_process.shared` (status, timing, telemetry and the pushed
target in shared memory), :mod:`~tracker.loop_process.wire` (calls, replies, carried errors).
"""
