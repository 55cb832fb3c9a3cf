"""Published airplane data.

Ryan Navion (four-seat general-aviation airplane), from R. C. Nelson, *Flight Stability and
Automatic Control*, 2nd ed., McGraw-Hill, 1998, Appendix B (geometric, mass and aerodynamic
data of the Navion; the data go back to Teper, *Aircraft Stability and Control Data*, Systems
Technology Inc. TR 176-1, 1969). Flight condition of the data: sea level, u0 = 176 ft/s.

    W = 2750 lb, S = 184 ft², b = 33.4 ft, c̄ = 5.7 ft,
    I_x = 1048, I_y = 3000, I_z = 3530 slug·ft², I_xz = 0

Longitudinal derivatives (stability axes, per rad): C_L = 0.41, C_D = 0.05, C_Lα = 4.44,
C_Dα = 0.33, C_mα = −0.683, C_Lq = 3.8, C_mq = −9.96, C_Lδe = 0.355, C_mδe = −0.923
(C_mα̇ = −4.36 is left out of ``navion_longitudinal_aero``, which the paper's example 3 runs
without; add the term ``"alphadot_hat"`` with that value to include it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from flightid.aircraft.aero import AeroModel
from flightid.aircraft.airplane import Airplane
from flightid.aircraft.units import FT, FT2, SLUG_FT2, isa_density, lb_weight_to_kg
from flightid.errors import InputError, InputTypeError, describe

__all__ = [
    "AIRPLANES",
    "NAVION_TRIM_SPEED",
    "airplane_from_table",
    "navion",
    "navion_longitudinal_aero",
]

# Nelson (1998), Appendix B, Navion flight condition: u0 = 176 ft/s at sea level.
NAVION_TRIM_SPEED = 176.0 * FT  # m/s (53.64 m/s)


def navion(*, altitude: float = 0.0, thrust_input: str | None = "thrust") -> Airplane:
    """The Navion (Nelson 1998, Appendix B), SI units; ISA density at ``altitude`` (m)."""
    return Airplane(
        mass=lb_weight_to_kg(2750.0),  # W = 2750 lb
        Ix=1048.0 * SLUG_FT2,
        Iy=3000.0 * SLUG_FT2,
        Iz=3530.0 * SLUG_FT2,
        Ixz=0.0,
        S=184.0 * FT2,
        b=33.4 * FT,
        cbar=5.7 * FT,
        density=isa_density(altitude),
        thrust_input=thrust_input,
        thrust_inclination=0.0,
        name="Navion",
    )


def navion_longitudinal_aero(elevator: str = "de") -> tuple[AeroModel, dict[str, float]]:
    """Linear longitudinal aerodynamic model of the Navion and its values (Nelson 1998, App. B).

    C_D = C_D0 + C_Dα α;  C_L = C_L0 + C_Lα α + C_Lq q̂ + C_Lδe δe;
    C_m = C_m0 + C_mα α + C_mq q̂ + C_mδe δe, with α measured from the reference (trim) body
    axis, so C_L0 = 0.41 and C_D0 = 0.05 are the trim values and C_m0 = 0.
    """
    aero = AeroModel(
        {
            "CD": ["1", "alpha"],
            "CL": ["1", "alpha", "qhat", elevator],
            "Cm": ["1", "alpha", "qhat", elevator],
        }
    )
    values = {
        "CD_0": 0.05,
        "CD_alpha": 0.33,
        "CL_0": 0.41,
        "CL_alpha": 4.44,
        "CL_qhat": 3.8,
        f"CL_{elevator}": 0.355,
        "Cm_0": 0.0,
        "Cm_alpha": -0.683,
        "Cm_qhat": -9.96,
        f"Cm_{elevator}": -0.923,
    }
    return aero, values


# Airplanes by name, for case files (model.airplane.library = "navion").
AIRPLANES = {"navion": navion}


def airplane_from_table(table: Mapping[str, Any]) -> Airplane:
    """An ``Airplane`` from a table of its fields (SI units), e.g. a case file's
    ``[model.airplane]``; ``library = "navion"`` starts from a published airplane (thrust
    folded into the coefficients) and the other keys replace its fields. With ``altitude``
    and no ``density`` the ISA density at that altitude is used.

    Raises:
        InputError: an unknown key or library name, or a bad value (the message names it).
    """
    if not isinstance(table, Mapping):
        raise InputTypeError(
            f"airplane: expected a table of Airplane fields, got {describe(table)}"
        )
    fields = {f.name for f in dataclasses.fields(Airplane)}
    settings = dict(table)
    unknown = sorted(set(settings) - fields - {"library"})
    if unknown:
        raise InputError(
            f"airplane.{unknown[0]}: unknown key; allowed: {sorted(fields | {'library'})}"
        )
    if "library" in settings:
        name = settings.pop("library")
        if name not in AIRPLANES:
            raise InputError(f"airplane.library: expected one of {sorted(AIRPLANES)}, got {name!r}")
        base = AIRPLANES[name](thrust_input=None)
        if "altitude" in settings and "density" not in settings:
            settings["density"] = None  # ISA density at the given altitude
        return dataclasses.replace(base, **settings)
    # every model needs mass, I_y, S, c̄; I_x, I_z, b only the lateral and 6-DOF ones
    if any(name not in settings for name in ("mass", "Iy", "S", "cbar")):
        missing = [
            name for name in ("mass", "Ix", "Iy", "Iz", "S", "b", "cbar") if name not in settings
        ]
        raise InputError(
            f"airplane.{missing[0]}: missing; an airplane needs {missing} (SI units; a "
            "longitudinal-only airplane may leave out Ix, Iz, b) or "
            f"library = one of {sorted(AIRPLANES)}"
        )
    return Airplane(**settings)
