"""ionav-viz: replay drives, inject GNSS outages, compare INS dead reckoning with the IDNN.

Data flows one way:

    sources (``iovnbd``)  ->  ``Drive``  ->  navigation (``windows``, ``ins``, ``idnn``,
    ``metrics``, ``evaluate``)  ->  results  ->  logging (``rerun_log``)  ->  ``cli`` wires them.

The conventions every module follows are written once, in :mod:`ionav_viz.drive`.
"""

__version__ = "0.1.0"
