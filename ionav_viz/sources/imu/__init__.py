"""The IMU as a log records it, characterised in one place: its axes (:mod:`.axes`), its mount on
the car (:mod:`.mount`), its samples' nature and rate (:mod:`.samples`), its clock against the
receiver's (:mod:`.clock`); :mod:`.character` runs them in order for the readers and returns the
:class:`ionav_viz.core.imu.ImuCharacter` the drive carries."""
