"""Readers: IO-VNBD CSV and MCAP logs into one in-memory :class:`~ionav_viz.core.drive.Drive`, name
resolution (paths, bundled scenarios, run names), and the MCAP writer.

Sources import nothing from navigation: they only produce drives."""
