"""Whether a point lies inside the support of the data a global model was fitted to.

A polynomial fitted over many maneuvers answers anywhere, also where no data were flown: in
the empty corner of the flight envelope (high α at high Mach, say) inside the box of the
data, "hidden extrapolation". Three measures flag it, all on every prediction:

- **distance**: in support coordinates v = (x − c)/r (the data box is [−1, 1]^m,
  ``flightid.globalmodel.variables``) the distance d_k(x₀) from the point to its k-th nearest
  reference sample (the data thinned to one sample per ``spacing_s`` (0.1 s) per maneuver, so a long
  steady stretch does not count as many), against d_ref, the ``quantile`` (0.99) of the same
  distance among the reference samples themselves (their (k+1)-th neighbour, the first being
  the sample itself): ``distance_ratio = d_k / d_ref``;
- **leverage** (model specific, catches a polynomial's blow-up at the edge of its data):
  h₀ = φ₀ᵀ(ΦᵀΦ)⁻¹φ₀ of the model's regressors φ₀ at the point, against the largest leverage
  h_max = max_i h_ii of the fitted samples: ``leverage_ratio = h₀ / h_max`` (the regression
  textbook's criterion for hidden extrapolation).

- **range**: beyond the data's range [low, high] of any variable by more than
  ``margin`` × (high − low) (``support_margin``, 0.02). A point just below the lowest α flown
  or above the highest Mach can have data samples near it in the other variables, so that its
  k-NN distance and its leverage stay small (a low-order polynomial extrapolates smoothly a
  little way), while the coefficient there is not known from the data at all.

A point is ``outside`` when it is beyond the range, ``distance_ratio > factor`` (2) or
``leverage_ratio > 1``; ``reason`` names the criteria that fired, joined by ``+`` in the
order range, distance, leverage (``""``, ``"range"``, ``"distance"``, ``"leverage"``,
``"range+distance"``, ``"distance+leverage"``, ``"range+distance+leverage"`` …).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.globalmodel.variables import GlobalModelError

__all__ = ["Support", "thinned_indices", "leverages", "beyond_range", "REASONS"]

# the criteria in the order ``reason`` names them
REASONS = ("range", "distance", "leverage")

# above this many reference samples the set is thinned evenly further (k-NN cost and the size
# of a saved model)
MAX_REFERENCE = 20000


def thinned_indices(
    maneuver_index: np.ndarray, dt: float | None, spacing_s: float, max_reference: int
) -> np.ndarray:
    """Indices of one sample per ``spacing_s`` seconds in each maneuver (every sample when
    ``dt`` is unknown), evenly thinned to at most ``max_reference``."""
    maneuver_index = np.asarray(maneuver_index)
    step = 1 if dt is None or spacing_s <= 0 else max(1, int(round(spacing_s / dt)))
    chosen = []
    for value in np.unique(maneuver_index):
        rows = np.flatnonzero(maneuver_index == value)
        chosen.append(rows[::step])
    index = np.sort(np.concatenate(chosen)) if chosen else np.zeros(0, dtype=int)
    if index.size > max_reference:
        index = index[np.linspace(0, index.size - 1, max_reference).round().astype(int)]
    return np.unique(index)


def beyond_range(X: np.ndarray, low: np.ndarray, high: np.ndarray, margin: float) -> np.ndarray:
    """True (n,) where a point of X (n, m, signal units) lies below ``low`` or above ``high``
    of any variable by more than ``margin`` × (high − low) (module docstring)."""
    X = np.asarray(X, dtype=float)
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    # allowed excess per variable: margin · (high − low); 0 for a variable the data held constant
    allowance = margin * (high - low)
    below = X < low - allowance
    above = X > high + allowance
    return np.any(below | above, axis=1)


def leverages(regressors: np.ndarray, xtx_inv: np.ndarray) -> np.ndarray:
    """h = φᵀ (ΦᵀΦ)⁻¹ φ for each row φ of ``regressors`` (n,)."""
    # h_i = φ_iᵀ (ΦᵀΦ)⁻¹ φ_i
    return np.einsum("ij,jk,ik->i", regressors, xtx_inv, regressors)


@dataclass(frozen=True, eq=False)
class Support:
    """The data support of a model (module docstring).

    Attributes:
        reference: thinned data samples in support coordinates (R, m).
        k: which nearest reference sample the distance is taken to.
        d_ref: the ``quantile`` of the reference samples' own k-NN distance.
        factor: ``distance_ratio`` above which a point is outside.
        spacing_s: thinning interval of the reference set, s.
        quantile: the quantile behind ``d_ref``.
    """

    reference: np.ndarray
    k: int
    d_ref: float
    factor: float
    spacing_s: float
    quantile: float

    @classmethod
    def from_data(
        cls,
        V: np.ndarray,
        maneuver_index: np.ndarray,
        dt: float | None,
        *,
        k: int = 5,
        spacing_s: float = 0.1,
        quantile: float = 0.99,
        factor: float = 2.0,
        max_reference: int = MAX_REFERENCE,
    ) -> Support:
        """The support of the data V (N, m, support coordinates) sampled every ``dt`` s."""
        from scipy.spatial import cKDTree

        V = np.asarray(V, dtype=float)
        reference = V[thinned_indices(maneuver_index, dt, spacing_s, max_reference)]
        if reference.shape[0] <= k + 1:
            raise GlobalModelError(
                f"support: expected more than k + 1 = {k + 1} reference samples after "
                f"thinning to one per {spacing_s} s, got {reference.shape[0]}"
            )
        # (k+1)-th neighbour of each reference sample: the first is the sample itself
        distances, _ = cKDTree(reference).query(reference, k=k + 1)
        d_ref = float(np.quantile(distances[:, -1], quantile))
        if not d_ref > 0:
            scale = float(np.max(np.ptp(reference, axis=0))) or 1.0
            d_ref = 1e-9 * scale
        return cls(reference, int(k), d_ref, float(factor), float(spacing_s), float(quantile))

    def distance_ratio(self, V: np.ndarray) -> np.ndarray:
        """d_k(v) / d_ref for points v (n, m) in support coordinates."""
        from scipy.spatial import cKDTree

        distances, _ = cKDTree(self.reference).query(np.asarray(V, dtype=float), k=self.k)
        d_k = distances[:, -1] if distances.ndim == 2 else distances
        return d_k / self.d_ref

    def measure(
        self,
        V: np.ndarray,
        leverage_ratio: np.ndarray,
        out_of_range: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
        """(distance_ratio, leverage_ratio, outside, reason) of points v (n, m);
        ``out_of_range`` (n,) marks the points beyond the data's range (``beyond_range``;
        default none)."""
        distance_ratio = self.distance_ratio(V)
        leverage_ratio = np.asarray(leverage_ratio, dtype=float)
        far = distance_ratio > self.factor
        high = leverage_ratio > 1.0
        ranged = (
            np.zeros(far.shape, dtype=bool)
            if out_of_range is None
            else np.asarray(out_of_range, dtype=bool).reshape(far.shape)
        )
        flags = np.column_stack([ranged, far, high])
        reason = tuple(
            "+".join(name for name, hit in zip(REASONS, row, strict=True) if hit) for row in flags
        )
        return distance_ratio, leverage_ratio, flags.any(axis=1), reason

    def to_dict(self) -> dict:
        return {
            "k": self.k,
            "spacing_s": self.spacing_s,
            "quantile": self.quantile,
            "factor": self.factor,
            "d_ref": self.d_ref,
            "reference": self.reference.tolist(),
        }

    @classmethod
    def from_dict(cls, entry: dict) -> Support:
        reference = np.asarray(entry["reference"], dtype=float)
        return cls(
            reference=reference,
            k=int(entry["k"]),
            d_ref=float(entry["d_ref"]),
            factor=float(entry["factor"]),
            spacing_s=float(entry["spacing_s"]),
            quantile=float(entry["quantile"]),
        )
