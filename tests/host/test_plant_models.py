"""The plant's machine models (issue 53): each folder of plant_rt/models/ defines one descriptor
(plant_model_desc_t), registered by one line in plant_rt/core/plant_models.c, and the registered models are
exactly plant.eds's Motor model.model ValueNames, each descriptor's id its own generated OD_PLANT_MODEL_<NAME>.
A model's own record ("Model <name>") is a scenario's [motor] keys."""

from __future__ import annotations

import re

from bench.eds import eds_path, model_records, value_names
from bench.paths import REPO
from bench.scenario.settings import param_tables

MODELS = REPO / "plant_rt" / "models"
DESC_RE = re.compile(r"const plant_model_desc_t (\w+) = \{(.*?)\n\};", re.S)


def descriptors() -> dict[str, tuple[str, str, str]]:
    """Descriptor variable -> (folder, .id, .name) of every model folder."""
    out = {}
    for src in sorted(MODELS.glob("*/*.c")):
        for var, body in DESC_RE.findall(src.read_text()):
            ident = re.search(r"\.id = (\w+)", body)
            name = re.search(r'\.name = "(\w+)"', body)
            assert ident and name, f"{src}: {var} without .id or .name"
            out[var] = (src.parent.name, ident.group(1), name.group(1))
    return out


def registered() -> list[str]:
    return re.findall(r"X\((plant_model_\w+)\)", (REPO / "plant_rt" / "core" / "plant_models.c").read_text())


def test_each_model_folder_has_one_registered_descriptor() -> None:
    found = descriptors()
    folders = sorted(p.name for p in MODELS.iterdir() if p.is_dir())
    assert sorted(f for f, _, _ in found.values()) == folders  # one descriptor a folder
    assert sorted(registered()) == sorted(found)  # each registered by its line


def test_the_registered_models_are_the_eds_value_names() -> None:
    from bench.eds import load

    var = load("plant")["Motor model"]["model"]
    names = value_names(eds_path("plant"), var)
    found = descriptors()
    assert sorted(n for _, _, n in found.values()) == sorted(names)
    for _, ident, name in found.values():
        assert ident == f"OD_PLANT_MODEL_{name.upper()}", (ident, name)


def test_a_models_record_is_a_scenario_motor_key() -> None:
    assert "Model harmonic" in model_records()
    motor = param_tables()["motor"]
    for key in ("psi_5_Wb", "psi_7_Wb", "cogging_Nm", "cogging_periods"):
        assert motor[key].obj == "Model harmonic", key
