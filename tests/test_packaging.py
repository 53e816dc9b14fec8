import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_code_package_is_listed_in_pyproject_and_the_configs_ship_whole():
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    code = {".".join(p.relative_to(ROOT).parent.parts) for d in ("zrp_ga", "hydra_plugins") for p in (ROOT / d).rglob("__init__.py")}
    assert not (ROOT / "hydra_plugins" / "__init__.py").exists()  # Hydra's namespace package
    assert code | {"zrp_ga.conf"} == set(setup["packages"])
    assert setup["package-data"]["zrp_ga.conf"] == ["**/*.yaml"]


def test_compiled_code_is_never_cached_inside_the_package():
    import numpy as np

    from zrp_ga import kinematics, robots
    from zrp_ga.operators import reverse_segments

    kinematics.forward(robots.get("puma560"), np.zeros((2, 6)))
    reverse_segments(np.zeros((1, 4)), np.array([0]), np.array([3]))
    package = ROOT / "zrp_ga"
    assert not [p for p in package.rglob("*") if p.suffix in (".nbi", ".nbc")]
