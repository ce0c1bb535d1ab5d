"""The shipped IDNN model (``idnn/``: weights and metadata), installed as package data of ``ionav_viz.models``."""
