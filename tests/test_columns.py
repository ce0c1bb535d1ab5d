"""The recording's line-strip columns, built as one Arrow array, against Rerun's own conversion
of the same strips one by one (an independent computation of the same column)."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from ionav_viz.viz import columns


@pytest.fixture
def tracks():
    """Three outages of four windows: (outages, windows + 1, 2) points, as the estimators' tracks."""
    return np.random.default_rng(7).normal(size=(3, 5, 2)) * 100.0


def test_growing_strips_are_the_start_then_one_more_point_each_window(tracks):
    expected = [tracks[s, : k + 1] for s in range(3) for k in range(5)]
    assert len(expected) == 15 and len(expected[0]) == 1 and len(expected[-1]) == 5
    got = columns.line_strips_2d(*columns.growing(tracks))
    assert got.equals(rr.components.LineStrip2DBatch(expected).as_arrow_array())
    geo = columns.geo_line_strings(*columns.growing(tracks))
    assert geo.equals(rr.components.GeoLineStringBatch(expected).as_arrow_array())


def test_ragged_and_stacked_strips(tracks):
    strips = [tracks[0, :2], tracks[1], tracks[2, 1:4]]
    got = columns.line_strips_2d(*columns.ragged(strips))
    assert got.equals(rr.components.LineStrip2DBatch(strips).as_arrow_array())
    whole = columns.line_strips_2d(*columns.stacked(tracks))
    assert whole.equals(rr.components.LineStrip2DBatch(list(tracks)).as_arrow_array())
    empty = columns.line_strips_2d(*columns.ragged([]))
    assert len(empty) == 0


def test_a_column_logs_one_strip_per_row(tracks, tmp_path):
    """Rerun takes the Arrow column as it is: each row reads back as its strip."""
    from rerun.chunk import RrdReader

    rec = rr.RecordingStream("ionav-viz-test", recording_id="columns")
    rec.save(tmp_path / "c.rrd")
    n = 15
    rec.send_columns("strips", indexes=[rr.TimeColumn("time", duration=np.arange(n, dtype=float))],
                     columns=rr.LineStrips2D.columns(strips=columns.line_strips_2d(*columns.growing(tracks))))
    rec.flush()
    rec.disconnect()
    rows = []
    for chunk in RrdReader(tmp_path / "c.rrd").stream():
        if str(chunk.entity_path) == "/strips":
            batch = chunk.to_record_batch()
            rows += batch.column(next(c for c in batch.schema.names if c.endswith(":strips"))).to_pylist()
    assert len(rows) == n
    np.testing.assert_allclose(np.array(rows[7][0]), tracks[1, :3].astype(np.float32))
