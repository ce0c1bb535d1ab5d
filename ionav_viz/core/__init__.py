"""The bottom layer: the drive model and its conventions, errors, units, the time grid, atomic files.

Imports nothing else from ionav_viz."""
