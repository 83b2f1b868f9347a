"""Fixtures for the model tests: synthetic datasets."""

from __future__ import annotations

import pytest

from cosim_plugins.identify import synthetic as syn
from cosim_plugins.identify.dataset import Dataset

BIAS_HZ = (0.0, 0.0, 2.4)  # steering offset that holds the synthetic swimmer's weight


def synthetic_dataset(root, plant, rows, seed, noise_mm=0.1, names=None) -> Dataset:
    """Simulate ``plant`` on the paper's paths (or ``names`` of them), write raw logs, read them back."""
    cases = syn.paper_cases()
    if names:
        cases = {k: cases[k] for k in names}
    files = syn.write_cases(root, plant, rows, cases, seed=seed, bias_hz=BIAS_HZ,
                            defects=syn.Defects(noise_mm=noise_mm))
    return Dataset.from_paths(files)


@pytest.fixture(scope="session")
def rich_data(tmp_path_factory):
    """(train, test) datasets from the richer synthetic plant (6 + 2 logs of 1500 rows)."""
    from cosim_plugins.models.physical import synthetic_plant

    plant = synthetic_plant().predict
    root = tmp_path_factory.mktemp("rich")
    train = synthetic_dataset(root / "train", plant, 1500, seed=3,
                              names=["circle_+0", "circle_-30", "circle_+90", "racetrack_+0", "racetrack_+45",
                                     "racetrack_-45"])
    test = synthetic_dataset(root / "test", plant, 1500, seed=4, names=["circle_+45", "racetrack_-30"])
    return train, test


@pytest.fixture(scope="session")
def make_dataset():
    """The :func:`synthetic_dataset` helper, for tests that need their own plant or noise."""
    return synthetic_dataset
