"""The drive simulator: synthetic drives in the exact IO-VNBD format, honest to real car sensors."""
