import numpy as np
import pytest

# zrp_ga's launcher's and sweeper's settings (hydra/launcher=zrp_ga and its presets; hydra/sweeper=zrp_ga,
# which the default hparams_search=none chooses) in Hydra's ConfigStore, as Hydra's plugin discovery
# stores them when it finds the plugins: hydra-core 1.3 does not find them in an editable install
# (pip install -e, which the tests run from; zrp-ga registers them itself), and a test that composes
# configs would otherwise depend on an earlier test having imported them.
import hydra_plugins.zrp_ga_launcher.config
import hydra_plugins.zrp_ga_sweeper.sweeper  # noqa: F401


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
