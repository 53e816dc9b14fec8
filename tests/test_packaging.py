import os
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_code_package_is_listed_in_pyproject_and_the_configs_ship_whole():
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    code = {".".join(p.relative_to(ROOT).parent.parts) for d in ("zrp_ga", "hydra_plugins") for p in (ROOT / d).rglob("__init__.py")}
    assert not (ROOT / "hydra_plugins" / "__init__.py").exists()  # Hydra's namespace package
    assert code | {"zrp_ga.conf"} == set(setup["packages"])
    assert setup["package-data"]["zrp_ga.conf"] == ["**/*.yaml"]


def test_compiled_code_is_never_cached_inside_the_package(monkeypatch):
    import numpy as np

    from zrp_ga import robots
    from zrp_ga.core import compiled
    from zrp_ga.model import kinematics

    monkeypatch.setenv("ZRP_GA_KERNELS", "compiled")
    kinematics.forward(robots.get("puma560"), np.zeros((2, 6)))
    from zrp_ga.model import _kernels

    assert _kernels.forward_kernel.signatures  # the compiled kernel ran (loaded from the cache, or compiled now)
    package = ROOT / "zrp_ga"
    assert not [p for p in package.rglob("*") if p.suffix in (".nbi", ".nbc")]
    if not os.environ.get("NUMBA_CACHE_DIR"):
        assert list(compiled.cache_dir().rglob("_kernels.forward_kernel-*.nbi"))  # cached where the module says


def test_hydra_only_through_its_public_interfaces():
    """No import from hydra._internal, no private field read or written, no method of Hydra's
    (or OmegaConf's) classes replaced: what broke every command under hydra-core 1.4."""
    import re

    private = re.compile(r"hydra\._internal|_internal import|\._content\b|\._instances\b|\._return_value\b|_set_parent\("
                         r"|\b(Hydra|ConfigLoaderImpl|Singleton|JobReturn|Plugins|OmegaConf|DictConfig)\.\w+\s*=[^=]")  # fmt: skip
    found = [f"{p.relative_to(ROOT)}:{k}: {line.strip()}" for d in ("zrp_ga", "hydra_plugins") for p in (ROOT / d).rglob("*.py")
             for k, line in enumerate(p.read_text().splitlines(), 1) if private.search(line)]  # fmt: skip
    assert not found, "\n".join(found)
