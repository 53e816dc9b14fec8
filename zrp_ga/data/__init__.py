


def resolve(name: str):
    """A file named in a config: ``pkg:REL`` is a file shipped in zrp_ga/data (e.g.
    ``pkg:ur10_ipa/series_b_joint_configurations.csv``), anything else a path."""
    import importlib.resources
    from pathlib import Path

    if name.startswith("pkg:"):
        return Path(str(importlib.resources.files("zrp_ga.data").joinpath(name[4:])))
    return Path(name).expanduser()
