"""HDF5 data sets: schema, round trip, and clear errors on bad files."""

import json

import h5py
import numpy as np
import pytest

from fhnn.data.dataset import SPLITS, read_dataset, write_dataset
from fhnn.errors import DataFormatError

from .conftest import small_dataset


@pytest.fixture(scope="module")
def dataset():
    return small_dataset("noisy_flow")


@pytest.fixture
def written(dataset, tmp_path):
    return write_dataset(dataset, tmp_path / "d.h5")


def test_schema_matches_spec(written, dataset):
    with h5py.File(written, "r") as f:
        assert f.attrs["format"] == "fhnn-trajectories"
        assert f.attrs["format_version"] == 2
        for key in ("scenario", "seed", "dt", "actuation", "obs_noise", "version"):
            assert key in f.attrs
        params = json.loads(f.attrs["scenario_params"])
        assert {"kx", "ky", "phase", "amp"} == set(params["modes"][0])
        body = json.loads(f.attrs["body_params"])
        assert {"M", "rho", "A", "m_ax", "m_ay", "c_l", "c_q"} <= set(body)
        assert body["c_q"] == {"law": "reynolds", "c_inf": 0.6, "c_0": 0.4, "sigma_ref": 0.2}
        for name in SPLITS:
            n, t = dataset[name].n_traj, dataset[name].n_times
            assert f[name]["t"].shape == (t,)
            assert f[name]["t"][0] == 0.0
            for key, shape in (
                ("states", (n, t, 4)),
                ("states_clean", (n, t, 4)),
                ("derivs", (n, t, 4)),
                ("forces", (n, t, 2)),
                ("actuation", (n, 2, 3, 3)),
            ):
                assert f[name][key].shape == shape
                assert f[name][key].dtype == np.float64


def test_round_trip(written, dataset):
    back = read_dataset(written)
    assert back.scenario_params == dataset.scenario_params
    assert back.body_params == dataset.body_params
    for name in SPLITS:
        for key, array in dataset[name].arrays().items():
            np.testing.assert_array_equal(back[name].arrays()[key], array)
    # the ground truth is rebuilt from the file alone
    eom = back.equations()
    s = back.train.states_clean[0, 5]
    np.testing.assert_allclose(
        np.asarray(eom(s, back.train.t[5], back.train.forces[0, 5])), back.train.derivs[0, 5], rtol=1e-13
    )


def _corrupt(path, edit):
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: f.attrs.__delitem__("format"), "not an fhnn data set (no 'format' attribute)"),
        (lambda f: f.attrs.__setitem__("format", "other"), "format is 'other'"),
        (lambda f: f.attrs.__setitem__("format_version", 3), "unsupported format_version 3"),
        (lambda f: f.attrs.__delitem__("body_params"), "missing attribute(s) body_params"),
        (lambda f: f.__delitem__("val"), "missing group /val"),
        (lambda f: f["test"].__delitem__("derivs"), "missing dataset /test/derivs"),
        (
            lambda f: (
                f["train"].__delitem__("forces"),
                f["train"].create_dataset("forces", data=np.zeros((2, 3))),
            ),
            "/train/forces has shape (2, 3), expected",
        ),
        (
            lambda f: f["train"]["states"].__setitem__((0, 0, 0), np.nan),
            "/train/states has 1 NaN or infinite value(s)",
        ),
        (lambda f: f.attrs.__setitem__("scenario_params", "{not json"), "not valid JSON"),
        (
            lambda f: f.attrs.__setitem__("scenario", "vortex"),
            "bad scenario or body metadata (unknown scenario 'vortex'",
        ),
    ],
)
def test_bad_files_name_the_problem(written, edit, message):
    _corrupt(written, edit)
    with pytest.raises(DataFormatError) as info:
        read_dataset(written)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_truncated_foreign_and_missing_files(written, tmp_path):
    data = written.read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 3])
    with pytest.raises(DataFormatError, match="not a readable HDF5 file"):
        read_dataset(tmp_path / "cut.h5")
    (tmp_path / "text.h5").write_text("hello")
    with pytest.raises(DataFormatError, match="not a readable HDF5 file"):
        read_dataset(tmp_path / "text.h5")
    with h5py.File(tmp_path / "foreign.h5", "w") as f:
        f["x"] = 1
    with pytest.raises(DataFormatError, match="not an fhnn data set"):
        read_dataset(tmp_path / "foreign.h5")
    with pytest.raises(DataFormatError, match="no such file"):
        read_dataset(tmp_path / "absent.h5")


def test_write_is_atomic(dataset, tmp_path, monkeypatch):
    target = tmp_path / "d.h5"

    def boom(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(h5py.Group, "create_dataset", boom)
    with pytest.raises(RuntimeError):
        write_dataset(dataset, target)
    assert list(tmp_path.iterdir()) == []  # neither the target nor a temporary file
    with pytest.raises(DataFormatError, match="output folder .* does not exist"):
        write_dataset(dataset, tmp_path / "missing" / "d.h5")


def test_force_residual_is_the_recorded_force_less_the_sinusoids_of_jax_actuation_force():
    """The NumPy residual against the model's own JAX sinusoids: zero (exactly) where the forces
    are those sinusoids, the recorded forces where a trajectory has no sinusoids, the difference
    elsewhere; per-trajectory times."""
    import jax
    import jax.numpy as jnp

    from fhnn.physics.actuation import actuation_force, force_residual, sample_actuation

    rng = np.random.default_rng(3)
    params = sample_actuation(rng, 3)
    params[1] = 0.0  # forcing known only as samples
    t = np.sort(rng.uniform(0.0, 30.0, (3, 50)), axis=1)
    sinusoids = np.asarray(
        jax.vmap(jax.vmap(actuation_force, in_axes=(None, 0)))(jnp.asarray(params), jnp.asarray(t))
    )
    forces = sinusoids.copy()
    forces[1] = rng.normal(size=(50, 2))
    forces[2, 7] += [0.25, -0.5]
    residual = force_residual(params, t, forces)
    assert np.all(residual[0] == 0.0)
    np.testing.assert_array_equal(residual[1], forces[1])
    expected = np.zeros((50, 2))
    expected[7] = [0.25, -0.5]
    np.testing.assert_allclose(residual[2], expected, rtol=0, atol=1e-12)
    assert np.count_nonzero(residual[2]) == 2
