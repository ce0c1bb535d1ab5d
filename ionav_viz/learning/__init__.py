"""Learning: the IDNN (:mod:`.idnn`), its training and fine-tuning (:mod:`.training`), what it
was trained on (:mod:`.provenance`) and where it is out of its depth (:mod:`.domain`). Above
:mod:`ionav_viz.nav`, whose windows, tracks and filters it uses."""
