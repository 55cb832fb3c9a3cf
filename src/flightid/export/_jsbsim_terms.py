"""The terms of a flightid aerodynamic model as JSBSim function expressions.

Each signal of the term language (``flightid.aircraft.equations.SIGNALS`` and the control
and thrust inputs) becomes an XML expression over JSBSim properties that evaluates to the
signal in flightid's units (m/s, rad, rad/s, N, non-dimensional rates); a term, a product of
signal powers, splines ``(x − k)₊`` and absolute values ``|x|``, becomes a ``<product>`` of
those expressions. JSBSim works in ft, slug, lbf: the factors below convert.

    V, u, v, w     = 0.3048 · velocities/{vt,u-aero,v-aero,w-aero}-fps          (m/s)
    alpha, beta    = aero/alpha-rad, aero/beta-rad
    p, q, r        = velocities/{p,q,r}-aero-rad_sec
    phat, rhat     = {p,r} · (b/2) / velocities/vt-fps   (with V0: the constant b/2V0)
    qhat           = q · (c̄/2) / velocities/vt-fps       (with V0: c̄/2V0)
    theta, phi     = attitude/theta-rad, attitude/phi-rad
    Mach           = velocities/mach      (V over the speed of sound of JSBSim's atmosphere)
    Vrel, dVrel    = V/V0, V/V0 − 1
    alphadot_hat   = aero/alphadot-rad_sec · c̄/2V   (rule ``ALPHADOT_RULE``)
    betadot_hat    = aero/betadot-rad_sec · b/2V    (rule ``BETADOT_RULE``)

(JSBSim's own aero/bi2vel and aero/ci2vel are not used: JSBSim 1.3 updates them after the
aerodynamics section's own functions, where the coefficients are computed, so these would
see the airspeed of the previous time step.)
    controls       = the property each is mapped to (default ``DEFAULT_CONTROLS``), rad
    thrust input   = 4.4482216152605 · flightid/thrust-lbs                       (N)

A signal with no entry here (the α–q model's measured q̄ and a_x, an unmapped control) is
refused with ``JSBSimExportError`` naming the coefficient, the term and the signal.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping

from flightid.errors import InputError

__all__ = [
    "ALPHADOT_RULE",
    "BETADOT_RULE",
    "DEFAULT_CONTROLS",
    "FT_M",
    "LBF_N",
    "THRUST_PROPERTY",
    "JSBSimExportError",
    "SignalMap",
    "number",
]

FT_M = 0.3048  # m per ft
LBF_N = 4.4482216152605  # N per lbf
# the property carrying the thrust magnitude T (lbf) of an airplane with a thrust input
THRUST_PROPERTY = "flightid/thrust-lbs"
# flightid control name → JSBSim property (rad, the model's own sign convention)
DEFAULT_CONTROLS = {
    "de": "fcs/elevator-pos-rad",
    "da": "fcs/left-aileron-pos-rad",
    "dr": "fcs/rudder-pos-rad",
}
ALPHADOT_RULE = (
    "alphadot-from-previous-step: flightid solves the α̇ terms implicitly with the forces of "
    "the same instant; JSBSim's aero/alphadot-rad_sec is the α̇ of its previous time step"
)
BETADOT_RULE = (
    "betadot-from-previous-step: flightid solves the β̇ terms implicitly with the forces of "
    "the same instant; JSBSim's aero/betadot-rad_sec is the β̇ of its previous time step"
)


class JSBSimExportError(InputError):
    """The model, airplane or arguments cannot be written as a JSBSim aircraft; the message
    names the term, quantity or argument and what JSBSim would need."""


def number(value: float) -> str:
    """Shortest text that reads back as the same float."""
    return repr(float(value))


def _value(value: float) -> ET.Element:
    element = ET.Element("value")
    element.text = number(value)
    return element


def _property(name: str) -> ET.Element:
    element = ET.Element("property")
    element.text = name
    return element


def _product(*children: ET.Element) -> ET.Element:
    element = ET.Element("product")
    element.extend(children)
    return element


class SignalMap:
    """Signal name → JSBSim expression (a fresh XML element per use).

    Args:
        b_ft, cbar_ft: span and chord, ft (``b_ft`` None for a longitudinal-only airplane).
        reference_speed: V0, m/s, or None.
        rate_speed: "V" (p̂ = p b/2V …) or "V0" (with the constant V0).
        controls: flightid control name → JSBSim property.
        thrust_input: the airplane's thrust channel name, or None.
    """

    def __init__(
        self,
        b_ft: float | None,
        cbar_ft: float,
        reference_speed: float | None,
        rate_speed: str,
        controls: Mapping[str, str],
        thrust_input: str | None,
    ) -> None:
        self.b_ft = b_ft
        self.cbar_ft = cbar_ft
        self.reference_speed = reference_speed
        self.rate_speed = rate_speed
        self.controls = dict(controls)
        self.thrust_input = thrust_input
        self.rules: set[str] = set()

    def _half_length_over_speed(self, length_ft: float) -> ET.Element:
        """length/(2 V_n), s: the constant length/(2 V0), or length/2 over
        velocities/vt-fps (not aero/bi2vel, aero/ci2vel: module docstring)."""
        if self.rate_speed == "V0":
            # length/(2 V0), V0 in ft/s
            return _value(length_ft / (2.0 * self.reference_speed / FT_M))
        element = ET.Element("quotient")
        element.extend([_value(length_ft / 2.0), _property("velocities/vt-fps")])
        return element

    def _span(self, signal: str) -> float:
        if self.b_ft is None:
            raise JSBSimExportError(
                f"signal {signal!r}: needs the span b, which the airplane leaves out "
                "(a longitudinal-only airplane); give Airplane.b"
            )
        return self.b_ft

    def expression(self, signal: str) -> ET.Element:
        """The JSBSim expression of ``signal`` in flightid's units; ``KeyError`` if none."""
        simple = {
            "alpha": "aero/alpha-rad",
            "beta": "aero/beta-rad",
            "p": "velocities/p-aero-rad_sec",
            "q": "velocities/q-aero-rad_sec",
            "r": "velocities/r-aero-rad_sec",
            "theta": "attitude/theta-rad",
            "phi": "attitude/phi-rad",
            "Mach": "velocities/mach",
        }
        if signal in simple:
            return _property(simple[signal])
        speeds = {
            "V": "velocities/vt-fps",
            "u": "velocities/u-aero-fps",
            "v": "velocities/v-aero-fps",
            "w": "velocities/w-aero-fps",
        }
        if signal in speeds:
            # m/s = 0.3048 · ft/s
            return _product(_value(FT_M), _property(speeds[signal]))
        if signal in ("phat", "rhat"):
            rate = f"velocities/{signal[0]}-aero-rad_sec"
            span = self._span(signal)
            return _product(_property(rate), self._half_length_over_speed(span))
        if signal == "qhat":
            return _product(
                _property("velocities/q-aero-rad_sec"),
                self._half_length_over_speed(self.cbar_ft),
            )
        if signal in ("Vrel", "dVrel"):
            return self._speed_ratio(signal)
        if signal in ("alphadot_hat", "betadot_hat"):
            return self._rate_of_angle(signal)
        if signal in self.controls:
            return _property(self.controls[signal])
        if signal == self.thrust_input:
            # N = 4.4482216152605 · lbf
            return _product(_value(LBF_N), _property(THRUST_PROPERTY))
        raise KeyError(signal)

    def _speed_ratio(self, signal: str) -> ET.Element:
        if self.reference_speed is None:
            raise JSBSimExportError(
                f"signal {signal!r}: needs the reference speed V0 (reference_speed, m/s)"
            )
        # V/V0 = vt_fps · (0.3048/V0)
        ratio = _product(_value(FT_M / self.reference_speed), _property("velocities/vt-fps"))
        if signal == "Vrel":
            return ratio
        # (V − V0)/V0 = V/V0 − 1
        element = ET.Element("sum")
        element.extend([ratio, _value(-1.0)])
        return element

    def _rate_of_angle(self, signal: str) -> ET.Element:
        if signal == "alphadot_hat":
            self.rules.add(ALPHADOT_RULE)
            rate = _property("aero/alphadot-rad_sec")
            return _product(rate, self._half_length_over_speed(self.cbar_ft))
        self.rules.add(BETADOT_RULE)
        rate = _property("aero/betadot-rad_sec")
        span = self._span(signal)
        return _product(rate, self._half_length_over_speed(span))

    def factor(self, key, coefficient: str, label: str) -> ET.Element:
        """One factor of a term: a signal, a spline (x − k)₊ = max(x − k, 0) or |x|."""
        from flightid.model.terms import Abs, Spline

        name = key.signal if isinstance(key, (Spline, Abs)) else key
        try:
            inner = self.expression(name)
        except KeyError:
            raise JSBSimExportError(
                f"coefficient {coefficient!r}, term {label!r}: the signal {name!r} has no "
                f"JSBSim counterpart; map a control with controls={{{name!r}: "
                "'fcs/…-pos-rad'}, or leave the term out (signals with a counterpart: "
                "V u v w alpha beta p q r phat qhat rhat theta phi Mach Vrel dVrel "
                "alphadot_hat betadot_hat, the controls and the thrust input)"
            ) from None
        if isinstance(key, Spline):
            # (x − k)₊ = max(x − k, 0)
            shifted = ET.Element("sum")
            shifted.extend([inner, _value(-key.knot)])
            element = ET.Element("max")
            element.extend([shifted, _value(0.0)])
            return element
        if isinstance(key, Abs):
            element = ET.Element("abs")
            element.append(inner)
            return element
        return inner

    def term(self, coefficient: str, term, value: float) -> ET.Element:
        """θ · x_1^n_1 · x_2^n_2 … of one term (integer powers as repeated factors)."""
        if term.is_constant:
            return _value(value)
        factors = [_value(value)]
        for key, power in term.factors:
            if not isinstance(power, int) or power < 1:
                raise JSBSimExportError(
                    f"coefficient {coefficient!r}, term {term.label!r}: power {power!r}; "
                    "expected a positive integer"
                )
            factors.extend(self.factor(key, coefficient, term.label) for _ in range(power))
        return _product(*factors)
