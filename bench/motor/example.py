"""The example motor folder (examples/motors/saturating_you2019/, docs/YOUR_MOTOR.md): You 2019's motor (the
plant's preset "you2019": R, pole pairs, the unsaturated Ld, Lq and psi of its Table A1) with a saturating,
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


# You 2019 Table A1 (the plant's preset you2019): psi_f, Ld0, Lq0; the saturation parameters ASSUMED.
EXAMPLE_MODEL = SaturationModel(
    psi_f_Wb=0.042, Ld0_H=4.46e-3, Lq0_H=4.54e-3, a=0.55, Id_A=8.0, b=0.4, Iq_A=5.0, kappa_H=2.5e-4, Ix_A=5.0
)
GRID_A = np.linspace(-16.0, 16.0, 33)  # 1 A steps, beyond the preset's 12 A trip level
NAME = "saturating_you2019"

SOURCE = (
    "R, pole pairs and the unsaturated Ld, Lq, psi: You 2019 Table A1 (the plant's preset you2019); the flux map: "
    "the analytic co-energy model of bench/motor/example.py, its saturation parameters ASSUMED (a = 0.55, Id = 8 A, "
    "b = 0.4, Iq = 5 A, kappa = 0.25 mH, Ix = 5 A), tabulated on a 33 x 33 grid of 1 A steps"
)
MOTOR_TOML = f"""\
# The example motor folder (docs/YOUR_MOTOR.md), written by `bench motor example DIR` (bench/motor/example.py).
[motor]
name = "You 2019 motor with an assumed saturating flux map"
source = "{SOURCE}"
pole_pairs = 5
R_ohm = 1.4

[flux_map]
file = "flux_map.csv"

[thermal]
# ASSUMED: a copper winding (0.00393 1/K) in a small machine: 2 K/W to the housing, 60 J/K, a 2-minute time constant
R_alpha_per_K = 0.00393
T_ref_degC = 20
T_amb_degC = 40
thermal_R_K_per_W = 2.0
thermal_C_J_per_K = 60.0
"""


def example_map(model: SaturationModel = EXAMPLE_MODEL, grid_A: np.ndarray = GRID_A) -> FluxMap:
    idg, iqg = np.meshgrid(grid_A, grid_A, indexing="ij")
    pd, pq = model.fluxes(idg, iqg)
    return FluxMap(grid_A.copy(), grid_A.copy(), pd, pq)


def write_example(folder: Path) -> Path:
    """The example motor folder at `folder` (created; an existing motor.toml there is refused)."""
    folder.mkdir(parents=True, exist_ok=True)
    desc = folder / "motor.toml"
    if desc.exists():
        raise FileExistsError(f"{desc} exists: choose an empty folder")
    fmap = example_map()
    lines = [
        "# id_A,iq_A in A; psi_d_Wb,psi_q_Wb in Wb (peak, per phase); a row per grid point",
        "id_A,iq_A,psi_d_Wb,psi_q_Wb",
    ]
    for i, a in enumerate(fmap.id_A):
        for j, b in enumerate(fmap.iq_A):
            lines.append(f"{a:g},{b:g},{float(fmap.psi_d_Wb[i, j])!r},{float(fmap.psi_q_Wb[i, j])!r}")
    (folder / "flux_map.csv").write_text("\n".join(lines) + "\n")
    desc.write_text(MOTOR_TOML)
    return folder
