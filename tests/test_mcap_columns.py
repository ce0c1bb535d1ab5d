"""CDR of many messages at once, both ways: :func:`ionav_viz.sources.cdr.decode_many` reads what
:func:`ionav_viz.sources.cdr.encode_many` writes, and refuses bytes that are not one layout; IMU samples binned a block at a time as one by one."""

import numpy as np

from ionav_viz.sources.cdr import decode_many, encode_many


def _layout_fields(rng, n):
    """Fields of every kind in an order that needs padding before most of them."""
    return [("u1", rng.integers(0, 255, n)), ("f8", rng.normal(size=n)), ("string", "imu_link"),
            ("i2", rng.integers(-30000, 30000, n)), ("f4", rng.normal(size=(n, 3)).astype(np.float32)),
            ("i1", -3), ("u8", rng.integers(0, 2**63, n, dtype=np.uint64)), ("string", "a"),
            ("u2", rng.integers(0, 65535, n)), ("f8", rng.normal(size=(n, 9))), ("i4", rng.integers(-2**31, 2**31 - 1, n)),
            ("u4", rng.integers(0, 2**32 - 1, n)), ("i8", rng.integers(-2**62, 2**62, n)), ("string", "")]


def test_decode_many_inverts_encode_many():
    rng = np.random.default_rng(7)
    n = 50
    fields = _layout_fields(rng, n)
    data = encode_many(fields, n)
    got = decode_many([(kind, np.shape(v)[1] if np.ndim(v) == 2 else 0) for kind, v in fields], data)
    assert got is not None
    for (kind, values), back in zip(fields, got):
        if kind == "string":
            assert back == values
        else:
            assert np.array_equal(np.broadcast_to(np.asarray(values, dtype=kind), back.shape), back), kind


def test_decode_many_refuses_what_is_not_one_layout():
    rng = np.random.default_rng(8)
    fields = [("f8", rng.normal(size=4)), ("string", "gps"), ("f8", rng.normal(size=4))]
    spec = [("f8", 0), ("string", 0), ("f8", 0)]
    data = encode_many(fields, 4)
    assert decode_many(spec, data) is not None
    assert decode_many(spec, np.pad(data, ((0, 0), (0, 3)))) is not None  # padding rosbags allows
    assert decode_many(spec, np.pad(data, ((0, 0), (0, 4)))) is None  # a longer message
    other = data.copy()
    other[2, 16] = ord("x")  # another frame of the same length
    assert decode_many(spec, other) is None
    big_endian = data.copy()
    big_endian[:, 1] = 0
    assert decode_many(spec, big_endian) is None
    assert decode_many(spec, data[:, :-1]) is None  # too short
    assert decode_many(spec, data[:0]) is None


def test_imu_bins_take_many_samples_as_one_by_one():
    """Samples added a block at a time reach ``prepare`` in the same blocks and sum to the same bins,
    bit for bit, as added one by one (over several of its blocks)."""
    from ionav_viz.sources.resample import IMU_BLOCK_SAMPLES, ImuBins

    rng = np.random.default_rng(9)
    n = 2 * IMU_BLOCK_SAMPLES + 12345
    samples = np.column_stack([np.sort(rng.uniform(0.0, n / 100.0, n)), rng.normal(size=(n, 6))])
    seen = {"one": [], "many": []}

    def bins(key):
        return ImuBins(0.1, keep_samples=True, prepare=lambda block: seen[key].append(len(block)) or block * 1.0)

    one, many = bins("one"), bins("many")
    for row in samples.tolist():
        one.add(tuple(row))
    start = 0
    while start < n:
        size = int(rng.integers(1, 20000))
        if rng.random() < 0.3:  # one by one between blocks
            many.add(tuple(samples[start].tolist()))
            size = 1
        else:
            many.add_many(samples[start : start + size])
        start += size
    for got, expected in zip(many.means(), one.means()):
        assert np.array_equal(got, expected)
    assert np.array_equal(many.kept_samples(), one.kept_samples())
    assert seen["many"] == seen["one"] == [IMU_BLOCK_SAMPLES, IMU_BLOCK_SAMPLES, 12345]
