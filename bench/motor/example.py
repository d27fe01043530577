"""The example motor folders (examples/motors/saturating_you2019/ and saturating_yao2020/, docs/YOUR_MOTOR.md): a
paper's motor (a plant preset's R, pole pairs, the unsaturated Ld, Lq and psi of its table) with a saturating,
cross-saturating flux map generated here from an analytic co-energy model, so that the map is reciprocal
(d psi_d/d iq = d psi_q/d id, as a lossless magnetic field's is) and its incremental inductances are known in
closed form (EXAMPLE_MODEL).

The model (every saturation parameter ASSUMED: chosen to give the tens of percent an IPM's inductances fall over its
current range, not taken from a machine):

    co-energy W'(id, iq) = psi_f id + Ld0 (a id^2/2 + (1-a) Id^2 g(id/Id)) + Lq0 (b iq^2/2 + (1-b) Iq^2 g(iq/Iq))
                           - kappa Ix id ln(1 + (iq/Ix)^2),          g(x) = x atan(x) - ln(1 + x^2)/2
    psi_d = dW'/did = psi_f + Ld0 (a id + (1-a) Id atan(id/Id)) - kappa Ix ln(1 + (iq/Ix)^2)
    psi_q = dW'/diq = Lq0 (b iq + (1-b) Iq atan(iq/Iq)) - 2 kappa id (iq/Ix) / (1 + (iq/Ix)^2)

At zero current the incremental inductances are Ld0 and Lq0 and the flux psi_f: the preset's values, so a drive
configured from the datasheet (the bench writes the map's small-signal values as the plant's Ld_H, Lq_H, psi_Wb)
starts exact, and the saturation is what it meets as the current grows."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.motor.fluxmap import FluxMap


@dataclass(frozen=True)
class SaturationModel:
    psi_f_Wb: float
    Ld0_H: float
    Lq0_H: float
    a: float  # the part of Ld that does not saturate
    Id_A: float  # the d-axis saturation current
    b: float
    Iq_A: float
    kappa_H: float  # cross-saturation
    Ix_A: float

    def fluxes(self, id_A: np.ndarray, iq_A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = iq_A / self.Ix_A
        pd = (
            self.psi_f_Wb
            + self.Ld0_H * (self.a * id_A + (1 - self.a) * self.Id_A * np.arctan(id_A / self.Id_A))
            - self.kappa_H * self.Ix_A * np.log1p(x * x)
        )
        pq = self.Lq0_H * (self.b * iq_A + (1 - self.b) * self.Iq_A * np.arctan(iq_A / self.Iq_A)) - (
            2 * self.kappa_H * id_A * x / (1 + x * x)
        )
        return pd, pq

    def inductances(self, id_A: float, iq_A: float) -> dict[str, float]:
        """The exact incremental inductances of the model (not of the map's interpolant)."""
        x = iq_A / self.Ix_A
        ldd = self.Ld0_H * (self.a + (1 - self.a) / (1 + (id_A / self.Id_A) ** 2))
        lqq = self.Lq0_H * (self.b + (1 - self.b) / (1 + (iq_A / self.Iq_A) ** 2))
        lqq -= 2 * self.kappa_H * id_A * (1 - x * x) / ((1 + x * x) ** 2 * self.Ix_A)
        ldq = -2 * self.kappa_H * x / (1 + x * x)
        return {"Ldd_H": ldd, "Ldq_H": ldq, "Lqd_H": ldq, "Lqq_H": lqq}


GRID_A = np.linspace(-16.0, 16.0, 33)  # 1 A steps
THERMAL = """
[thermal]
# ASSUMED: a copper winding (0.00393 1/K) in a small machine: 2 K/W to the housing, 60 J/K, a 2-minute time constant
R_alpha_per_K = 0.00393
T_ref_degC = 20
T_amb_degC = 40
thermal_R_K_per_W = 2.0
thermal_C_J_per_K = 60.0
"""


@dataclass(frozen=True)
class Example:
    """An example motor folder: a paper's motor (a plant preset's R, pole pairs, unsaturated Ld, Lq, psi) with the
    co-energy saturation model above, its parameters ASSUMED."""

    title: str
    paper: str  # where the motor's own values come from
    pole_pairs: int
    R_ohm: float
    model: SaturationModel
    thermal: str = THERMAL

    def source(self) -> str:
        m = self.model
        return (
            f"R, pole pairs and the unsaturated Ld, Lq, psi: {self.paper}; the flux map: the analytic co-energy "
            f"model of bench/motor/example.py, its saturation parameters ASSUMED (a = {m.a:g}, Id = {m.Id_A:g} A, "
            f"b = {m.b:g}, Iq = {m.Iq_A:g} A, kappa = {m.kappa_H * 1e3:g} mH, Ix = {m.Ix_A:g} A), tabulated on a "
            f"{len(GRID_A)} x {len(GRID_A)} grid of 1 A steps"
        )

    def motor_toml(self) -> str:
        return (
            "# An example motor folder (docs/YOUR_MOTOR.md), written by `bench motor example DIR` "
            "(bench/motor/example.py).\n"
            f'[motor]\nname = "{self.title}"\nsource = "{self.source()}"\npole_pairs = {self.pole_pairs}\n'
            f'R_ohm = {self.R_ohm!r}\n\n[flux_map]\nfile = "flux_map.csv"\n{self.thermal}'
        )


EXAMPLES = {
    # You 2019 Table A1 (the plant's preset you2019)
    "saturating_you2019": Example(
        "You 2019 motor with an assumed saturating flux map",
        "You 2019 Table A1 (the plant's preset you2019)",
        5,
        1.4,
        SaturationModel(0.042, 4.46e-3, 4.54e-3, a=0.55, Id_A=8.0, b=0.4, Iq_A=5.0, kappa_H=2.5e-4, Ix_A=5.0),
    ),
    # Yao 2020 Table I, the low-power motor (the plant's preset yao2020_low): its identification study's motor
    "saturating_yao2020": Example(
        "Yao 2020 low-power motor with an assumed saturating flux map",
        "Yao 2020 Table I, the low-power motor (the plant's preset yao2020_low)",
        4,
        2.2,
        SaturationModel(0.12, 5.5e-3, 5.5e-3, a=0.55, Id_A=8.0, b=0.4, Iq_A=5.0, kappa_H=3.0e-4, Ix_A=5.0),
        thermal="",
    ),
}
DEFAULT = "saturating_you2019"
EXAMPLE_MODEL = EXAMPLES[DEFAULT].model


def example_map(model: SaturationModel = EXAMPLE_MODEL, grid_A: np.ndarray = GRID_A) -> FluxMap:
    idg, iqg = np.meshgrid(grid_A, grid_A, indexing="ij")
    pd, pq = model.fluxes(idg, iqg)
    return FluxMap(grid_A.copy(), grid_A.copy(), pd, pq)


def write_example(folder: Path, name: str = DEFAULT) -> Path:
    """The example motor folder `name` (EXAMPLES) at `folder` (created; an existing motor.toml there is refused)."""
    ex = EXAMPLES[name]
    desc, table = folder / "motor.toml", folder / "flux_map.csv"
    for f in (desc, table):
        if f.exists():
            raise FileExistsError(f"{f} exists: choose an empty folder")
    folder.mkdir(parents=True, exist_ok=True)
    fmap = example_map(ex.model)
    lines = [
        "# id_A,iq_A in A; psi_d_Wb,psi_q_Wb in Wb (peak, per phase); a row per grid point",
        "id_A,iq_A,psi_d_Wb,psi_q_Wb",
    ]
    for i, a in enumerate(fmap.id_A):
        for j, b in enumerate(fmap.iq_A):
            lines.append(f"{a:g},{b:g},{float(fmap.psi_d_Wb[i, j])!r},{float(fmap.psi_q_Wb[i, j])!r}")
    # each file whole or not at all: written beside, then renamed
    for f, text in ((table, "\n".join(lines) + "\n"), (desc, ex.motor_toml())):
        part = f.with_name(f.name + ".part")
        part.write_text(text)
        part.replace(f)
    return folder
