"""Unit conversions, ISA density and the Airplane definition."""

import math

import numpy as np
import pytest

from flightid.aircraft import Airplane, navion
from flightid.aircraft import units as U
from flightid.errors import InputError


def test_conversion_factors_match_their_definitions():
    # international foot and pound (exact by definition)
    assert U.ft(1.0) == pytest.approx(0.3048, abs=0)
    assert U.lbf(1.0) == pytest.approx(4.4482216152605, rel=1e-15)
    # 1 slug = 1 lbf·s²/ft = 14.5939029 kg (NIST SP 811, appendix B)
    assert U.slug(1.0) == pytest.approx(14.5939029372, rel=1e-10)
    # 1 slug·ft² = 1.35581795 kg·m² (NIST SP 811)
    assert U.slug_ft2(1.0) == pytest.approx(1.3558179483, rel=1e-9)
    assert U.deg(180.0) == pytest.approx(math.pi, rel=1e-15)
    assert U.lb_weight_to_kg(1.0) == pytest.approx(0.45359237, rel=1e-15)
    np.testing.assert_allclose(U.ft([1.0, 2.0]), [0.3048, 0.6096])


def test_isa_density_at_sea_level_and_tropopause():
    # ICAO standard atmosphere: ρ(0) = 1.2250 kg/m³, ρ(11 km) = 0.36392 kg/m³
    assert U.isa_density(0.0) == pytest.approx(1.225, rel=1e-6)
    assert U.isa_density(11000.0) == pytest.approx(0.36392, rel=1e-4)
    with pytest.raises(InputError, match="altitude_m"):
        U.isa_density(20000.0)


def test_navion_data_in_si():
    # Nelson (1998) App. B: W = 2750 lb, S = 184 ft², b = 33.4 ft, I_x = 1048 slug·ft²
    airplane = navion()
    assert airplane.mass == pytest.approx(1247.38, rel=1e-5)
    assert airplane.S == pytest.approx(17.0942, rel=1e-5)
    assert airplane.b == pytest.approx(10.1803, rel=1e-5)
    assert airplane.Ix == pytest.approx(1420.90, rel=1e-5)
    assert airplane.rho == pytest.approx(1.225, rel=1e-6)
    assert airplane.gamma == pytest.approx(airplane.Ix * airplane.Iz)


def test_airplane_rejects_bad_values():
    good = dict(mass=1000.0, Ix=1.0, Iy=1.0, Iz=1.0, Ixz=0.0, S=10.0, b=10.0, cbar=1.0)
    with pytest.raises(InputError, match="Airplane.mass"):
        Airplane(**{**good, "mass": -1.0})
    with pytest.raises(InputError, match="Γ"):
        Airplane(**{**good, "Ixz": 2.0})
    with pytest.raises(InputError, match="density"):
        Airplane(**good, density=-1.0)
    with pytest.raises(InputError, match="thrust_input"):
        Airplane(**good, thrust_input="not a name")
    assert Airplane(**good, altitude=1000.0).rho == pytest.approx(U.isa_density(1000.0))
