"""Aerodynamic models linear in their parameters, written the way an engineer writes them.

Each aerodynamic coefficient is a sum of named derivatives times regressors [RP-1153 2.16–2.18]:

    C(t) = θ0 + θ1 x1(t) + … + θ_{n−1} x_{n−1}(t)

where every regressor x_j is a term of the ``flightid.model.terms`` language — a product of
signal powers such as ``"beta"``, ``"alpha*phat"``, ``"beta^3"``, ``"alpha*dr"``, a
first-order spline in α such as ``"spline1(alpha,0.15)"`` = max(α − 0.15, 0), or the constant
``"1"`` — built from states, inputs and the non-dimensional rates p̂ = p b / 2V, q̂ = q c̄ / 2V,
r̂ = r b / 2V.

Coefficients (body axes, stability axes):

    CX, CY, CZ  force coefficients along body x, y, z
    CD, CL      drag and lift (may replace CX, CZ; converted with α, RP-1153 2.15)
    Cl, Cm, Cn  rolling, pitching and yawing moment coefficients

A coefficient may also be given as a mapping ``{parameter name: term}``, which names the
parameters as a reference case does: ``{"CD": {"CD0": "1", "CDV": "Vrel", "CDa": "alpha"}}``.

Parameter names otherwise follow NASA notation: coefficient, underscore, the term's signals
joined by underscores with powers appended — ``Cl`` × ``"beta"`` → ``Cl_beta`` (C_lβ),
``CY`` × ``"alpha*beta"`` → ``CY_alpha_beta`` (C_Yαβ), ``CY`` × ``"beta^3"`` → ``CY_beta3``
(C_Yβ³), ``Cn`` × ``"1"`` → ``Cn_0``. A spline factor is written as its signal, ``_s`` and the
knot with "." as "p" and "-" as "m": ``CL`` × ``"spline1(alpha,0.15)"`` → ``CL_alpha_s0p15``
(C_L of (α − 0.15)₊), ``Cm`` × ``"spline1(alpha,-0.05)"`` → ``Cm_alpha_sm0p05``.

Inside the compiled equations of motion the model is carried as numeric tables
(``AeroTables``): for every term the coefficient it belongs to, the index of its parameter in
the full parameter vector θ, and its factors (signal index, power, spline flag and knot). No
Python object reaches
the compiled functions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError, InputTypeError, describe
from flightid.model.parameters import Parameter, Parameters
from flightid.model.terms import Abs, Spline, Term, TermError, parse_terms

__all__ = ["AeroModel", "AeroTables", "COEFFICIENTS", "parameter_name"]

# Order of the coefficient vector inside the compiled equations.
COEFFICIENTS = ("CX", "CY", "CZ", "CD", "CL", "Cl", "Cm", "Cn")


def parameter_name(coefficient: str, term: Term) -> str:
    """NASA-style parameter name, e.g. ("Cl", alpha*phat) → "Cl_alpha_phat"; constant → "Cl_0";
    ("CL", spline1(alpha,0.15)) → "CL_alpha_s0p15"."""
    # Term.identifier: "0" for the constant, "alpha_beta3" for α·β³, "alpha_s0p15" for
    # spline1(alpha,0.15) (see flightid.model.terms)
    return f"{coefficient}_{term.identifier}"


@dataclass(frozen=True)
class AeroTables:
    """Numeric form of an ``AeroModel`` for the compiled equations (all int64 / float64).

    term_coef[k]     index into ``COEFFICIENTS`` of term k's coefficient
    term_param[k]    index of term k's parameter in the full parameter vector θ
    factor_start     factors of term k are entries factor_start[k] : factor_start[k+1]
    factor_signal    signal index of each factor
    factor_power     integer power of each factor
    factor_spline    1 if the factor is the spline (x − knot)₊ of its signal, 2 if it is the
                     absolute value |x|, 0 if the signal
    factor_knot      the spline's knot (0 for plain signals), signal units
    """

    term_coef: np.ndarray
    term_param: np.ndarray
    factor_start: np.ndarray
    factor_signal: np.ndarray
    factor_power: np.ndarray
    factor_spline: np.ndarray
    factor_knot: np.ndarray


class AeroModel:
    """Per-coefficient lists of regressor terms, linear in the parameters.

    Args:
        coefficients: mapping ``{coefficient: [term, ...]}``, e.g.
            ``{"Cl": ["1", "beta", "phat", "rhat", "da", "dr", "alpha*phat"]}``; terms are
            strings of the term language or ``Term`` objects. A coefficient given as a
            mapping ``{parameter name: term}`` names its parameters (default: NASA names).

    Raises:
        InputError: unknown coefficient, CX/CZ mixed with CD/CL, an empty term list, or a
            parameter name that is not an identifier or is used twice.
        TermError: a malformed or repeated term.
    """

    def __init__(
        self, coefficients: Mapping[str, Sequence[str | Term] | Mapping[str, str | Term]]
    ) -> None:
        if not isinstance(coefficients, Mapping):
            raise InputTypeError(
                "coefficients: expected a mapping {coefficient: [terms]}, "
                f"got {describe(coefficients)}"
            )
        parsed: dict[str, tuple[Term, ...]] = {}
        names: dict[tuple[str, str], str] = {}
        for name, terms in coefficients.items():
            if isinstance(terms, Mapping):
                for pname in terms:
                    if not isinstance(pname, str) or not pname.isidentifier():
                        raise InputError(
                            f"coefficients[{name!r}]: parameter names must be identifiers, "
                            f"got {describe(pname)}"
                        )
                labels = list(terms)
                terms = list(terms.values())
            else:
                labels = None
            if name not in COEFFICIENTS:
                raise InputError(
                    f"coefficients: unknown coefficient {name!r}; expected one of {COEFFICIENTS}"
                )
            if isinstance(terms, str):
                raise InputTypeError(
                    f"coefficients[{name!r}]: expected a list of terms, got the string {terms!r}"
                )
            texts = [t.label if isinstance(t, Term) else t for t in terms]
            if not texts:
                raise InputError(f"coefficients[{name!r}]: expected at least one term, got none")
            parsed[name] = tuple(parse_terms(texts))
            if labels is not None:
                for pname, term in zip(labels, parsed[name], strict=True):
                    names[(name, term.label)] = pname
        body = {"CX", "CZ"} & set(parsed)
        wind = {"CD", "CL"} & set(parsed)
        if body and wind:
            raise InputError(
                f"coefficients: give the longitudinal forces either in body axes (CX, CZ) or as "
                f"drag and lift (CD, CL), not both; got {sorted(body | wind)}"
            )
        self._terms = parsed
        self._names = names
        all_names = self.parameter_names
        repeated = sorted({n for n in all_names if all_names.count(n) > 1})
        if repeated:
            raise InputError(f"coefficients: parameter names used twice: {repeated}")

    # ------------------------------------------------------------------ views
    @property
    def coefficients(self) -> tuple[str, ...]:
        return tuple(self._terms)

    def terms(self, coefficient: str) -> tuple[Term, ...]:
        if coefficient not in self._terms:
            raise KeyError(
                f"no coefficient {coefficient!r} in this model; it has {list(self._terms)}"
            )
        return self._terms[coefficient]

    def parameter_name(self, coefficient: str, term: Term) -> str:
        """The name of the parameter of ``term`` in ``coefficient``: the one given, else the
        NASA-style ``parameter_name``."""
        return self._names.get((coefficient, term.label), parameter_name(coefficient, term))

    @property
    def parameter_names(self) -> list[str]:
        """Parameter names in model order (coefficients as given, terms as given)."""
        return [self.parameter_name(c, t) for c, terms in self._terms.items() for t in terms]

    @property
    def signals(self) -> tuple[str, ...]:
        """Names of all signals the terms use, in first-use order."""
        seen: dict[str, None] = {}
        for terms in self._terms.values():
            for term in terms:
                for name in term.signals:
                    seen.setdefault(name, None)
        return tuple(seen)

    @property
    def spec(self) -> dict[str, list[str] | dict[str, str]]:
        """The model as ``{coefficient: [term text, ...]}`` (canonical term labels), or
        ``{coefficient: {parameter name: term text}}`` where the names were given."""
        return {
            c: (
                {self.parameter_name(c, t): t.label for t in terms}
                if any((c, t.label) in self._names for t in terms)
                else [t.label for t in terms]
            )
            for c, terms in self._terms.items()
        }

    def __add__(self, other: AeroModel) -> AeroModel:
        """Union of two models with different coefficients (e.g. longitudinal + lateral)."""
        if not isinstance(other, AeroModel):
            return NotImplemented
        shared = sorted(set(self._terms) & set(other._terms))
        if shared:
            raise InputError(f"aero models: both define the coefficients {shared}")
        return AeroModel({**self.spec, **other.spec})

    def __repr__(self) -> str:
        inner = "; ".join(
            f"{c} = "
            + " + ".join(
                self.parameter_name(c, t) + ("" if t.is_constant else f"·{t}") for t in terms
            )
            for c, terms in self._terms.items()
        )
        return f"AeroModel({inner})"

    # ------------------------------------------------------------------ parameters
    def parameters(
        self,
        values: Mapping[str, float] | None = None,
        *,
        fixed: Sequence[str] = (),
        scales: Mapping[str, float] | None = None,
    ) -> Parameters:
        """``Parameters`` for this model: values default to 0, all free except ``fixed``."""
        names = self.parameter_names
        values = dict(values or {})
        scales = dict(scales or {})
        for argument, given in (("values", values), ("scales", scales), ("fixed", fixed)):
            unknown = sorted(set(given) - set(names))
            if unknown:
                raise InputError(
                    f"{argument}: unknown parameter names {unknown}; this model's parameters: "
                    f"{names}"
                )
        return Parameters(
            Parameter(n, float(values.get(n, 0.0)), free=n not in fixed, scale=scales.get(n))
            for n in names
        )

    # ------------------------------------------------------------------ numeric forms
    def tables(self, signal_names: Sequence[str], parameters: Parameters) -> AeroTables:
        """Numeric tables against a signal list and the model's full parameter vector."""
        signal_index = {name: i for i, name in enumerate(signal_names)}
        term_coef, term_param, start = [], [], [0]
        factor_signal, factor_power, factor_spline, factor_knot = [], [], [], []
        for coefficient, terms in self._terms.items():
            for term in terms:
                pname = self.parameter_name(coefficient, term)
                if pname not in parameters:
                    raise InputError(
                        f"parameters: the aerodynamic model needs a parameter {pname!r}; "
                        f"got {parameters.names}"
                    )
                for key, power in term.factors:
                    spline = isinstance(key, Spline)
                    name = key.signal if isinstance(key, (Spline, Abs)) else key
                    if name not in signal_index:
                        raise TermError(
                            f"coefficient {coefficient!r}, term {term.label!r}: unknown signal "
                            f"{name!r}; available signals: {list(signal_names)}"
                        )
                    factor_signal.append(signal_index[name])
                    factor_power.append(power)
                    # 1: spline (x − knot)₊, 2: |x|, 0: the signal
                    factor_spline.append(1 if spline else 2 if isinstance(key, Abs) else 0)
                    factor_knot.append(key.knot if spline else 0.0)
                term_coef.append(COEFFICIENTS.index(coefficient))
                term_param.append(parameters.index(pname))
                start.append(len(factor_signal))
        as_int = lambda v: np.array(v, dtype=np.int64)  # noqa: E731
        return AeroTables(
            as_int(term_coef),
            as_int(term_param),
            as_int(start),
            as_int(factor_signal),
            as_int(factor_power),
            as_int(factor_spline),
            np.array(factor_knot, dtype=np.float64),
        )

    def regressors(self, coefficient: str, signals: Mapping[str, np.ndarray]) -> np.ndarray:
        """Regressor matrix (N, n_terms) of one coefficient from signal time histories."""
        terms = self.terms(coefficient)
        n = len(next(iter(signals.values()))) if signals else 0
        return np.column_stack([t.evaluate(signals, n) for t in terms])

    def evaluate(
        self, signals: Mapping[str, np.ndarray], values: Mapping[str, float]
    ) -> dict[str, np.ndarray]:
        """Coefficient time histories {coefficient: C(t)} for parameter values by name."""
        out = {}
        for coefficient, terms in self._terms.items():
            theta = np.array([values[self.parameter_name(coefficient, t)] for t in terms])
            out[coefficient] = self.regressors(coefficient, signals) @ theta
        return out
