"""The EMPS benchmark (a real linear positioning axis) as workbench measurements.

Janot, Gautier, Brunot, "Data Set and Reference Models of EMPS", 2019 (README beside the data in
``shared/data/emps``). The axis is prismatic: "angle" is the position ``qm`` in metres, "torque"
is force in newtons, "J" is the moved mass in kg, and the gain K is the drive gain
``gtau`` = 35.15 N/V. The command is ``vir`` (V). The published reference model,
``gtau·vir = M q'' + Fv q' + Fc sign q' + offset``, has our sign convention for the offset.
"""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

import numpy as np

from tracker.errors import DataError
from tracker.plant.model import AxisModel
from tracker.workbench.measurements.data import Measurement, validate, write_log

# The published reference parameters (inverse-dynamics least squares on DATA_EMPS).
PUBLISHED_PARAMS = MappingProxyType(
    {"inertia.J": 95.1089, "viscous.b": 203.5034, "coulomb.torque": 20.3935, "offset.torque": -3.1648}
)
# The authors' second model: direction-dependent friction.
PUBLISHED_ASYMMETRIC = MappingProxyType(
    {
        "viscous.b": 166.7,
        "viscous_asymmetry.negative": 240.4,
        "coulomb.torque": 20.14,
        "coulomb_asymmetry.negative": 20.63,
    }
)
GTAU_N_PER_V = 35.15
DEFAULT_DATA_DIR = Path(__file__).resolve().parents[4] / "shared" / "data" / "emps"


def load_emps(path: str | Path) -> tuple[Measurement, float]:
    """Read an EMPS ``.mat`` file. Returns (measurement with t s, u = vir V, theta = qm m; gtau N/V)."""
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    p = Path(path)
    try:
        mat = loadmat(str(p))
    except FileNotFoundError:
        raise DataError(f"{p}: no such file") from None
    except (OSError, ValueError, MatReadError) as exc:
        raise DataError(f"{p}: not a readable MATLAB file ({exc})") from None
    missing = [k for k in ("t", "qm", "vir") if k not in mat]
    if missing:
        raise DataError(f"{p}: missing variable {', '.join(missing)} (an EMPS file has t, qm, vir, gtau)")
    t = np.asarray(mat["t"], dtype=float).ravel()
    qm = np.asarray(mat["qm"], dtype=float).ravel()
    vir = np.asarray(mat["vir"], dtype=float).ravel()
    if not (t.size == qm.size == vir.size):
        raise DataError(f"{p}: t, qm and vir have different lengths ({t.size}, {qm.size}, {vir.size})")
    gain = float(np.asarray(mat["gtau"]).ravel()[0]) if "gtau" in mat else GTAU_N_PER_V
    return validate(Measurement(t, vir, qm, str(p))), gain


def convert_emps(mat_path: str | Path, csv_path: str | Path) -> Measurement:
    """Convert an EMPS ``.mat`` file to the workbench CSV log (t, u, theta); returns the log."""
    meas, _ = load_emps(mat_path)
    write_log(csv_path, meas)
    return meas


def emps_model(effects: tuple[str, ...] = ("offset",), gain_n_per_v: float = GTAU_N_PER_V) -> AxisModel:
    """A model of the EMPS axis with catalogue defaults (the fitter starts from the data itself)."""
    return AxisModel.create(gain_n_per_v, {}, effects)


__all__ = [
    "DEFAULT_DATA_DIR",
    "GTAU_N_PER_V",
    "PUBLISHED_ASYMMETRIC",
    "PUBLISHED_PARAMS",
    "convert_emps",
    "emps_model",
    "load_emps",
]
