"""The workbench for a PTZ camera: logs of commanded speed steps against measured angle, the
camera model (speed table, latency, acceleration limit, backlash, quantization), its k-step
prediction, least-squares fit, diagnosis, and the speed-table identification job.

A camera log is the DC log's CSV with ``speed_cmd`` (the signed speed step sent to the camera)
instead of ``u``; :func:`tracker.workbench.camera.log.is_camera_log` is the dispatch point the
``tracker model`` commands and the service use to route a log here.
"""
