"""What a flight log holds: its streams and their rates (``flightid.logs.streams``), the
flight modes and system-identification runs it records (``flightid.logs.modes``), the
excitation inputs in it (``flightid.logs.excitation``), the case-file lines that select
them (``flightid.logs.caselines``), and built-in signals such as Euler angles from the
attitude quaternion (``flightid.data.signals``). ``flightid inspect`` shows all of it.

numpy/scipy only; the figure is in ``flightid.report.log_figures``. The package sits at
the data layer; import from its modules.
"""
