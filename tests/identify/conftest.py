"""Fixtures for the identification tests: small synthetic raw logs."""

from __future__ import annotations

import pytest

from cosim_plugins.identify import synthetic as syn

BIAS_HZ = (0.0, 0.0, 2.4)  # steering offset that holds the synthetic swimmer's weight


@pytest.fixture(scope="session")
def small_logs(tmp_path_factory):
    """{'train': [4 paths], 'test': [2 paths]}: 1000-row logs from the richer synthetic plant."""
    from cosim_plugins.models.physical import synthetic_plant

    root = tmp_path_factory.mktemp("synthetic")
    cases = syn.paper_cases()
    plant = synthetic_plant().predict
    train = {k: cases[k] for k in ("circle_+0", "circle_+45", "racetrack_+0", "racetrack_-30")}
    test = {k: cases[k] for k in ("circle_-30", "racetrack_+90")}
    return {
        "train": syn.write_cases(root / "train", plant, 1000, train, seed=1, bias_hz=BIAS_HZ),
        "test": syn.write_cases(root / "test", plant, 1000, test, seed=2, bias_hz=BIAS_HZ),
    }
