import numpy as np
import pytest

# zrp_ga's launcher's settings (hydra/launcher=zrp_ga and its presets) in Hydra's ConfigStore, as
# Hydra's plugin discovery stores them when it finds the plugin: hydra-core 1.3 does not find it in
# an editable install (pip install -e, which the tests run from; zrp-ga registers it itself).
import hydra_plugins.zrp_ga_launcher.config  # noqa: F401


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
