"""Readers into one in-memory :class:`~ionav_viz.core.drive.Drive`: IO-VNBD CSV (``iovnbd``), message
logs (``message_log``, with the formats ``mcap_reader`` and ``rosbag_reader``), KITTI raw OXTS
folders (``kitti``), the 10 Hz grid they share (``resample``); name resolution, and the MCAP writer.

Sources import nothing from navigation: they only produce drives."""
