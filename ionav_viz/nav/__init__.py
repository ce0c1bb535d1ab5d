"""Navigation: the kernels (strapdown mechanisation, Kalman updates, the planar filter) and the
estimators built on them (INS dead reckoning, odometry, the EKF, the 3D GNSS/INS, external tracks),
their protocol for plug-ins, the 1-second windows they run on, sensor biases and track rebuilding.

Consumes only the drive model (:mod:`ionav_viz.core`) and the readers' plausibility limits. The IDNN
is in :mod:`ionav_viz.learning`, outage placement and the estimators' registry in
:mod:`ionav_viz.experiment`."""
