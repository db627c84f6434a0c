"""MJCF models of rmac-mj (installed as ``rmac_mj.models``); see README.md in this folder.

A model lives either in its own folder, menagerie style (``<name>/<name>.xml`` beside ``<name>/scene.xml``
and ``<name>/README.md``), or as a single file ``<name>.xml``.
"""

import pathlib

MODELS_DIR = pathlib.Path(__file__).resolve().parent


def available_models() -> list[str]:
    """Names of the shipped models, folder models and single files alike."""
    folders = {p.parent.name for p in MODELS_DIR.glob("*/*.xml") if p.stem == p.parent.name}
    return sorted(folders | {p.stem for p in MODELS_DIR.glob("*.xml")})


def model_path(name: str = "dc_pendulum", scene: bool = False) -> pathlib.Path:
    """Path of the MJCF of model ``name`` shipped with the package.

    Args:
      name: the model, e.g. ``"dc_pendulum"`` or ``"two_link_arm"``.
      scene: the model folder's ``scene.xml`` (the model with floor, light and camera) instead of the
        model itself; only folder models have one.
    """
    folder = MODELS_DIR / name
    path = folder / ("scene.xml" if scene else f"{name}.xml")
    if not path.is_file() and not scene:
        path = MODELS_DIR / f"{name}.xml"
    if not path.is_file():
        if scene and name in available_models():
            raise ValueError(
                f"model_path: model {name!r} has no scene.xml (only folder models have one)"
            )
        raise ValueError(f"model_path: no model named {name!r}; available: {available_models()}")
    return path
