import os
import re
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


# Private attributes of Hydra's and OmegaConf's objects (and the rest of Hydra's private API):
# a node's internals (_get_node, _value(), _content, _metadata, _parent, _get_parent), an
# object's __dict__, hydra._internal, Hydra's singletons' fields, and a method of their classes
# replaced. Matched in the text, whatever the object: zrp_ga and the launcher have no private
# attributes of these names of their own.
PRIVATE_HYDRA = re.compile(
    r"hydra\._internal|_internal import|\b_get_node\b|\._value\(|__dict__|\b_content\b|\b_metadata\b|\b_(get_|set_)?parent\b"
    r"|\._instances\b|\._return_value\b"
    r"|\b(Hydra|ConfigLoaderImpl|Singleton|JobReturn|Plugins|OmegaConf|DictConfig|ListConfig|HydraConfig)\.\w+\s*=[^=]")  # fmt: skip


def private_hydra_accesses(roots: list[Path]) -> list[str]:
    """Each line of the Python files under ``roots`` reaching into Hydra's or OmegaConf's
    private API (``PRIVATE_HYDRA``), as ``path:line: text``."""
    files: list[Path] = []
    for root in roots:
        files += [root] if root.is_file() else sorted(root.rglob("*.py"))
    return [f"{p}:{k}: {line.strip()}" for p in files for k, line in enumerate(p.read_text().splitlines(), 1)
            if PRIVATE_HYDRA.search(line)]  # fmt: skip


def test_hydra_only_through_its_public_interfaces():
    """No import from hydra._internal, no private field read or written, no method of Hydra's
    (or OmegaConf's) classes replaced: what broke every command under hydra-core 1.4."""
    found = private_hydra_accesses([ROOT / "zrp_ga", ROOT / "hydra_plugins"])
    assert not found, "\n".join(found)


PLANTED = [
    "node = cfg._get_node('a')",
    "value = node._value()",
    "cfg.__dict__['_content'] = {}",
    "content = vars(cfg)['_content']",
    "ref = cfg._metadata.ref_type",
    "root = node._parent",
    "root = node._get_parent()",
    "node._set_parent(None)",
    "from hydra._internal.hydra import Hydra",
    "from hydra._internal import utils",
    "import hydra._internal.utils",
    "Singleton._instances.clear()",
    "ret._return_value = 1",
    "OmegaConf.to_yaml = lambda c: ''",
    "HydraConfig.get = staticmethod(lambda: None)",
]
PUBLIC = [
    "OmegaConf.select(cfg, 'a.b', default=None)",
    "OmegaConf.update(cfg, 'a', 1, merge=True)",
    "with open_dict(cfg), read_write(cfg): del cfg['hydra']",
    "parents = [p.parent for p in paths]",
    "kept_parents = best(P)",
    "metadata = read_metadata(run)",
    "content = path.read_text()",
    "if OmegaConf.is_interpolation(cfg, 'x'): pass",
    "value = job.value()",
    "OmegaConf.to_yaml(cfg) == text",
]


def test_the_guard_finds_each_planted_private_access_and_no_public_call(tmp_path):
    """The guard of the test above on planted lines, each in a file of its own: each private
    access found, each public call left alone."""
    for k, line in enumerate(PLANTED + PUBLIC):
        (tmp_path / f"m{k}.py").write_text(f"x = 1\n{line}\n")
    found = {Path(f.split(":")[0]).name for f in private_hydra_accesses([tmp_path])}
    assert found == {f"m{k}.py" for k in range(len(PLANTED))}
