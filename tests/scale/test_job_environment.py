"""A sweep's job carries the environment variables that change a run: the framework's cache folder and
those the installed plugins name (hook ``cosim_register_environment``), and no other."""

from __future__ import annotations

from cosim.scale.jobs import client_env, env_keys


def test_the_keys_are_the_frameworks_and_the_plugins(monkeypatch):
    assert env_keys()[0] == "COSIM_CACHE"
    assert {"COSIM_FMU", "COSIM_DATASET"} <= set(env_keys())  # the lab's plant and dataset


def test_a_job_carries_the_set_ones_only(monkeypatch):
    monkeypatch.setenv("COSIM_CACHE", "/tmp/somewhere")
    monkeypatch.setenv("COSIM_DATASET", "quick")
    monkeypatch.delenv("COSIM_FMU", raising=False)
    monkeypatch.setenv("COSIM_UNRELATED", "x")
    carried = dict(client_env())
    assert carried == {"COSIM_CACHE": "/tmp/somewhere", "COSIM_DATASET": "quick"}
