"""MJCF models of rmac-mj (installed as ``rmac_mj.models``); see README.md in this folder."""

import pathlib

MODELS_DIR = pathlib.Path(__file__).resolve().parent


def model_path(name: str = "dc_pendulum") -> pathlib.Path:
    """Path of the MJCF file ``<name>.xml`` shipped with the package."""
    path = MODELS_DIR / f"{name}.xml"
    if not path.is_file():
        available = sorted(p.stem for p in MODELS_DIR.glob("*.xml"))
        raise ValueError(f"model_path: no model named {name!r}; available: {available}")
    return path
