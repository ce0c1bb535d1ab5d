"""The IDNN: feedback wiring, normalisation, determinism, safe and validated loading."""

import json
import pickle

import numpy as np
import pytest
import torch

from ionav_viz.core.errors import InputError
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.dataset.samples import samples_dir
from ionav_viz.learning.idnn import (
    IdnnModel,
    MinMax,
    ModelConfig,
    Normalisation,
    build_net,
    kinematic_weights,
    load_model,
    save_model,
)
from ionav_viz.learning.training import FitSettings, fit_network, train_models, training_examples
from ionav_viz.nav.bias import SensorBias
from ionav_viz.sources.iovnbd import read_iovnbd

IDENTITY = MinMax(0.0, 1.0)


class EchoFeedback(torch.nn.Module):
    """Returns its feedback input plus one: shows what the model is fed back."""

    def __init__(self, n_steps: int) -> None:
        super().__init__()
        self.n_steps = n_steps
        self.seen: list[torch.Tensor] = []
        self.dummy = torch.nn.Parameter(torch.zeros(1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        self.seen.append(x.detach().clone())
        return x[:, self.n_steps] + 1.0 + 0.0 * self.dummy


def _echo_model(n_steps=10) -> IdnnModel:
    norm = Normalisation(IDENTITY, IDENTITY, IDENTITY, IDENTITY)
    return IdnnModel(ModelConfig(n_steps_disp=n_steps, n_steps_yaw=n_steps), norm, EchoFeedback(n_steps), EchoFeedback(n_steps))


def test_prediction_feeds_back_its_own_output():
    """The echo net says one metre more than its feedback input, at any acceleration; the model
    takes off what a net says without acceleration beyond its feedback input (a drift), so this
    net's "+1" is removed and only what acceleration adds stays."""
    model = _echo_model()
    accel = np.zeros((2, 5, 10))
    out = model.predict_displacement(accel, first_prev_disp_m=np.array([5.0, 20.0]))
    # first window gets the last GNSS displacement, every later one the model's own output: here
    # the echo's drift of one metre a window, taken off
    np.testing.assert_allclose(out, [[5, 5, 5, 5, 5], [20, 20, 20, 20, 20]])
    # all sequences step together: one call per window, each with the whole batch twice (as
    # measured, and without acceleration)
    assert len(model.disp_net.seen) == 5 and all(x.shape == (4, 11) for x in model.disp_net.seen)
    np.testing.assert_allclose(model.disp_net.seen[1][:, 10], [5, 20, 5, 20])  # what was fed back


def test_a_window_without_acceleration_keeps_the_displacement():
    """A net that adds 0.3 m to every window drifts by 0.3 m a window at constant speed; a net that
    adds the window's mean acceleration (m/s^2 over 1 s, m/s) plus the same drift gains exactly that."""

    class Drifting(torch.nn.Module):
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return x[:, 10] + x[:, :10].mean(dim=1) + 0.3

    norm = Normalisation(IDENTITY, IDENTITY, IDENTITY, IDENTITY)
    model = IdnnModel(ModelConfig(n_steps_disp=10, n_steps_yaw=10), norm, Drifting(), None)
    cruise = model.predict_displacement(np.zeros((1, 30, 10)), np.array([25.0]))
    np.testing.assert_allclose(cruise[0], 25.0)  # not 25.3, 25.6, ... 34.0
    speeding_up = model.predict_displacement(np.full((1, 4, 10), 0.5), np.array([10.0]))
    np.testing.assert_allclose(speeding_up[0], [10.5, 11.0, 11.5, 12.0])


def test_prediction_adds_no_noise():
    model = _echo_model()
    a = model.predict_displacement(np.zeros((3, 4, 10)), np.array([1.0, 2.0, 3.0]))
    b = model.predict_displacement(np.zeros((3, 4, 10)), np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(a, b)


def test_training_feeds_noisy_gnss_displacement():
    drive = read_iovnbd(samples_dir() / "V-sim-quick-accel.csv")
    data = training_examples([(drive, SensorBias.none())], n_steps_disp=10, n_steps_yaw=10, phases=1)
    # teacher forcing: the feedback input of window k is the GNSS displacement of window k-1
    np.testing.assert_allclose(data.prev_disp_m[1:], data.disp_m[:-1])
    net = EchoFeedback(10)
    x = np.zeros((len(data), 11))
    x[:, 0] = np.arange(len(data))  # tag each example to find it after shuffling
    x[:, 10] = data.prev_disp_m
    fit_network(net, x, data.disp_m, FitSettings(lr=0.0, epochs=1, batch=256, seed=0, noise_col=10, noise_sd=0.5), label="t")
    seen = torch.cat(net.seen).numpy().astype(np.float64)
    example = np.rint(seen[:, 0]).astype(int)
    assert sorted(example) == list(range(len(data)))  # every example once per epoch
    noise = seen[:, 10] - x[example, 10]
    assert noise.std() == pytest.approx(0.5, rel=0.1) and abs(noise.mean()) < 0.05
    assert np.all(seen[:, 1:10] == 0)  # only the feedback column is perturbed


def test_min_max_round_trip_and_metadata_round_trip():
    x = np.array([-3.0, 0.5, 7.0])
    mm = MinMax.fit(x)
    np.testing.assert_allclose(mm.scale(x), [0.0, 0.35, 1.0])
    np.testing.assert_allclose(mm.unscale(mm.scale(x)), x)
    norm = Normalisation(mm, MinMax(0, 30), MinMax(-1, 1), MinMax(-1, 1))
    assert Normalisation.from_dict(json.loads(json.dumps(norm.to_dict()))) == norm


@pytest.fixture(scope="module")
def tiny_drives():
    drive = read_iovnbd(samples_dir() / "V-sim-roundabout-train-1.csv")
    return [(drive, SensorBias(0.0, 0.0, "test", 0.0))]


TINY = dict(epochs_disp=2, epochs_yaw=2, seed=3)


def test_tiny_model_trains_deterministically(tiny_drives):
    a = train_models(tiny_drives, ModelConfig(**TINY))
    b = train_models(tiny_drives, ModelConfig(**TINY))
    for na, nb in ((a.disp_net, b.disp_net), (a.yaw_net, b.yaw_net)):
        for (ka, va), (kb, vb) in zip(na.state_dict().items(), nb.state_dict().items()):
            assert ka == kb and torch.equal(va, vb)
    c = train_models(tiny_drives, ModelConfig(**{**TINY, "seed": 4}))
    assert not torch.equal(next(iter(a.disp_net.state_dict().values())), next(iter(c.disp_net.state_dict().values())))


@pytest.mark.parametrize("arch", ["idnn", "mlp", "rnn", "gru", "lstm"])
def test_saved_model_loads_and_predicts_the_same(tmp_path, tiny_drives, arch):
    model = train_models(tiny_drives, ModelConfig(arch=arch, **TINY))
    save_model(model, tmp_path / "m")
    loaded = load_model(tmp_path / "m")
    gyro = np.linspace(-0.3, 0.3, 40).reshape(4, 10)
    np.testing.assert_allclose(loaded.predict_yaw_rate(gyro), model.predict_yaw_rate(gyro), rtol=1e-6)
    meta = json.loads((tmp_path / "m" / "metadata.json").read_text())
    assert meta["config"]["arch"] == arch and meta["training"]["drives"][0]["name"] == "V-sim-roundabout-train-1"
    assert {"torch", "numpy", "ionav_viz"} <= set(meta["versions"]) and meta["validation"]["disp_mae_m"] > 0


@pytest.fixture()
def saved(tmp_path, tiny_drives):
    save_model(train_models(tiny_drives, ModelConfig(**TINY)), tmp_path / "m")
    return tmp_path / "m"


def test_missing_model(tmp_path):
    with pytest.raises(InputError, match=r"metadata.json missing"):
        load_model(tmp_path / "nothing")


def test_a_models_file_or_a_folder_of_folds_is_named_as_such(saved, tmp_path):
    """--model DIR/metadata.json was "DIR/metadata.json/metadata.json: cannot read it (Not a
    directory)", and cross-validate's output folder "metadata.json missing" with a hint to train
    one; now the file is named and its folder suggested, and the folds are pointed at."""
    with pytest.raises(InputError, match=r"metadata.json: a file; a model is the directory") as err:
        load_model(saved / "metadata.json")
    assert err.value.hint == f"give its directory ({saved})"
    folds = tmp_path / "cv"
    folds.mkdir()
    import shutil

    shutil.copytree(saved, folds / "fold-1")
    with pytest.raises(InputError, match=r"metadata.json missing") as err:
        load_model(folds)
    assert "cross-validate's fold models (fold-1): give one of them" in err.value.hint


def test_corrupted_metadata(saved):
    (saved / "metadata.json").write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_model(saved)


def test_metadata_without_normalisation(saved):
    meta = json.loads((saved / "metadata.json").read_text())
    del meta["normalisation"]
    (saved / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="incomplete or invalid metadata"):
        load_model(saved)


def test_weights_that_do_not_fit_the_architecture(saved):
    meta = json.loads((saved / "metadata.json").read_text())
    meta["config"]["n_steps_disp"] = 12
    (saved / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="do not fit"):
        load_model(saved)


def test_truncated_weights(saved):
    path = saved / "displacement.safetensors"
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(InputError, match="not a safetensors weights file"):
        load_model(saved)


class _Payload:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_pickle_payload_is_refused_and_never_executed(saved):
    marker = saved / "pwned"
    (saved / "displacement.safetensors").write_bytes(pickle.dumps(_Payload(str(marker))))
    with pytest.raises(InputError, match="pickled files are never loaded"):
        load_model(saved)
    torch.save({"x": _Payload(str(marker))}, saved / "yaw_rate.safetensors")
    with pytest.raises(InputError):
        load_model(saved)
    assert not marker.exists()


def test_kinematic_weights_by_hand():
    # 20 steps span both windows: trapezoid weights of the triangular kernel 1 - |tau|, tau = -0.9 .. 1.0
    np.testing.assert_allclose(kinematic_weights(20), np.r_[np.arange(1, 11), np.arange(9, -1, -1)] / 100.0)
    # 10 steps only see the window itself: the kernel 0.9, 0.8, ... 0 rescaled to sum to 1
    np.testing.assert_allclose(kinematic_weights(10), np.arange(9, -1, -1) / 45.0)
    for n in range(1, 21):
        assert kinematic_weights(n).sum() == pytest.approx(1.0)


@pytest.mark.parametrize("n_steps", [10, 14, 20])
def test_untrained_residual_net_is_exact_kinematics_for_constant_acceleration(n_steps):
    # With the learned correction switched off, d_t = d_{t-1} + sum(w a) * 1 s: for a constant
    # acceleration of 0.5 m/s^2 and 10.25 m in the window before the outage (speed 10.5 m/s at
    # its start), window k's displacement is its mean speed 10.5 + 0.5 (k + 1/2) = 10.75 + 0.5 k.
    norm = Normalisation(MinMax(-4.0, 4.0), MinMax(0.0, 40.0), MinMax(-1.0, 1.0), MinMax(-1.0, 1.0))
    net = build_net("idnn", n_steps, 8, 0.0, True, norm.skip_terms(True))
    with torch.no_grad():
        net.body[-1].weight.zero_()
        net.body[-1].bias.zero_()
    net.eval()
    model = IdnnModel(ModelConfig(n_steps_disp=n_steps), norm, net, None)
    out = model.predict_displacement(np.full((1, 6, n_steps), 0.5), np.array([10.25]))
    np.testing.assert_allclose(out[0], 10.75 + 0.5 * np.arange(6), atol=1e-4)


def test_learning_rate_falls_to_zero_over_the_tail():
    class Flat(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.linear = torch.nn.Linear(1, 1)

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.linear(x).squeeze(-1)

    net = Flat()
    x, y = np.zeros((100, 1)), np.ones(100)
    lrs = []
    real_step = torch.optim.Adamax.step

    def spy(self, *args, **kwargs):
        lrs.append(self.param_groups[0]["lr"])
        return real_step(self, *args, **kwargs)

    torch.optim.Adamax.step = spy
    try:
        fit_network(net, x, y, FitSettings(lr=0.01, epochs=10, batch=10, seed=0, decay_tail=0.5), label="t")
    finally:
        torch.optim.Adamax.step = real_step
    # 100 steps: constant for the first 50, then (100 - step) / 50 of the rate
    assert lrs[:51] == [0.01] * 51
    np.testing.assert_allclose(lrs[51:], 0.01 * (100 - np.arange(51, 100)) / 50)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_shipped_model_beats_dead_reckoning_on_the_bundled_test_drive(scenario):
    # the acceptance point: lower mean displacement CRSE and mean orientation-rate CRSE
    from ionav_viz.analysis.evaluate import evaluate_drive
    from ionav_viz.experiment.registry import resolve
    from ionav_viz.learning.idnn import default_model_dir

    result = evaluate_drive(read_iovnbd(samples_dir() / f"V-sim-{scenario}.csv"), 10, resolve(["ins", "idnn"], model=load_model(default_model_dir())))
    ins, idnn = result.metrics["ins"], result.metrics["idnn"]
    assert len(result.starts) == 59
    assert idnn["crse_m"].mean() < ins["crse_m"].mean()
    assert idnn["yaw_crse_radps"].mean() < ins["yaw_crse_radps"].mean()


@pytest.mark.parametrize("arch", ["idnn", "mlp"])
@pytest.mark.parametrize("feedback", [True, False])
@pytest.mark.parametrize("skip", [None, (0.7, -0.2)])
def test_the_numpy_inference_net_computes_what_the_torch_net_does(arch, feedback, skip):
    """Evaluation runs the feed-forward nets in numpy (no torch import); training makes them in
    torch. With the same weights both give the same outputs, the displacement net's fed-back input
    and the kinematic skip term included."""
    from ionav_viz.learning.idnn import NumpyFeedForward

    torch.manual_seed(3)
    n_steps = 10
    net = build_net(arch, n_steps, 16, 0.2, feedback, skip).eval()  # eval: dropout off, as in inference
    state = {k: v.detach().numpy() for k, v in net.state_dict().items()}
    numpy_net = NumpyFeedForward(state, n_steps, feedback, skip, latest_only=arch == "mlp")
    x = np.random.default_rng(3).uniform(-1.0, 2.0, (64, n_steps + int(feedback))).astype(np.float32)
    with torch.no_grad():
        expected = net(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(numpy_net(x), expected, rtol=1e-5, atol=1e-5)
    assert np.ptp(expected) > 0.01  # the inputs reach the output
