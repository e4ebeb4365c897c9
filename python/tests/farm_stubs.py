"""What the farm's tests without a cluster share: stand-ins for Dask's Client and LocalCluster
that stop a run where it would start a cluster, and one scene file per test module."""

import pytest

from test_render import _scene


class ClusterStarted(Exception):
    """Raised by the stand-ins for Client and LocalCluster: the run got as far as a cluster."""


@pytest.fixture
def no_cluster(monkeypatch):
    """Client and LocalCluster replaced by stand-ins that raise ClusterStarted."""
    import dask.distributed

    def refuse(*args, **kwargs):
        raise ClusterStarted()

    monkeypatch.setattr(dask.distributed, "Client", refuse)
    monkeypatch.setattr(dask.distributed, "LocalCluster", refuse)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """One scene file for the module: the probe renders reuse its loaded scene."""
    return _scene(tmp_path_factory.mktemp("scene"))
