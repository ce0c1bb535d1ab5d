"""The IO-VNBD dataset: the run catalog and LFS manifest, the bundled synthetic samples, verified downloads."""
