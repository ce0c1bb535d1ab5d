"""Experiment design: where the outages go (:mod:`.outages`, :mod:`.plan_file`) and which
estimators a run may name (:mod:`.registry`: the built-ins of :mod:`ionav_viz.nav` and
:mod:`ionav_viz.learning`, and plug-ins)."""
