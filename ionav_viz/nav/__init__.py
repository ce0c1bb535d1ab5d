"""Navigation: 1-second windows, outage placement, sensor biases, the estimators (INS dead
reckoning, the IDNN and plug-ins) and track rebuilding, and IDNN training.

Consumes only the drive model (:mod:`ionav_viz.core`)."""
