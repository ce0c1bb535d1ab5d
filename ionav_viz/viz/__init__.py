"""Visualisation: Rerun recordings of results, their styles, and headless screenshots.

Consumes only results (:mod:`ionav_viz.analysis`)."""
