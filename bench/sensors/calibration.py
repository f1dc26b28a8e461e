"""Counts -> mm calibration of an optical mouse: a 2x2 matrix with its id and date, applied to every sample.

The fit that produces the matrix (least squares over reference moves, ``sensors.md`` §5.2) lives in
``bench.metrology``; this module only holds, checks, stores and applies the result.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from bench.errors import ConfigError
from bench.metrology.mouse_calibration import MM_PER_INCH

__all__ = ["DEFAULT_CPI", "MM_PER_INCH", "CountsCalibration"]

#: An optical mouse's nominal resolution when nothing states another (counts per inch): the documents' sensors'
#: default, the station's `[mice] cpi` when it names none, and the simulated mice's.
DEFAULT_CPI = 800.0


@dataclass(frozen=True, eq=False)
class CountsCalibration:
    """Linear map from sensor counts to displacement, ``d_mm = A @ c`` (``sensors.md`` §4.11, §5.2).

    Parameters
    ----------
    matrix_mm_per_count : array_like, shape (2, 2)
        ``A`` in mm/count; row i gives displacement axis i from the two sensor count axes. A diagonal matrix is a
        per-axis scale; off-diagonal terms absorb mounting rotation and cross-talk.
    calibration_id : str
        Identifier stored with every sample (e.g. ``"ocm-xy-2026-11-23a"``).
    date : str
        ISO 8601 date of the calibration.
    nominal : bool
        True when the matrix comes from a nominal CPI, not from a measurement: reports must flag it.
    notes : str
        Surface, height, CPI register, reference instrument...
    """

    matrix_mm_per_count: np.ndarray
    calibration_id: str
    date: str
    nominal: bool = False
    notes: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        matrix = np.array(self.matrix_mm_per_count, dtype=float)
        if matrix.shape != (2, 2) or not np.all(np.isfinite(matrix)):
            raise ConfigError(
                f"calibration {self.calibration_id!r}: matrix_mm_per_count = "
                f"{self.matrix_mm_per_count!r}, expected a finite 2x2 matrix (mm/count)"
            )
        if abs(np.linalg.det(matrix)) < 1e-12:
            raise ConfigError(
                f"calibration {self.calibration_id!r}: matrix_mm_per_count is singular "
                f"(det = {np.linalg.det(matrix):.3g}), expected an invertible 2x2 matrix"
            )
        if not self.calibration_id:
            raise ConfigError("calibration: calibration_id is empty, expected a non-empty identifier")
        try:
            _dt.date.fromisoformat(self.date[:10])
        except (TypeError, ValueError):
            raise ConfigError(
                f"calibration {self.calibration_id!r}: date = {self.date!r}, expected an ISO date such as '2026-11-23'"
            ) from None
        matrix.setflags(write=False)
        object.__setattr__(self, "matrix_mm_per_count", matrix)

    @classmethod
    def from_scales(
        cls, x_mm_per_count: float, y_mm_per_count: float, *, calibration_id: str, date: str, notes: str = ""
    ) -> CountsCalibration:
        """Per-axis scales (mm/count), no cross terms."""
        return cls(np.diag([x_mm_per_count, y_mm_per_count]), calibration_id, date, notes=notes)

    @classmethod
    def from_cpi(cls, cpi: float, *, calibration_id: str | None = None, date: str | None = None) -> CountsCalibration:
        """The nominal scale ``25.4 / CPI`` mm/count on both axes, flagged ``nominal`` (not a calibration)."""
        if not cpi > 0:
            raise ConfigError(f"calibration: cpi = {cpi!r}, expected a positive counts-per-inch value")
        scale = MM_PER_INCH / cpi
        return cls(
            np.diag([scale, scale]),
            calibration_id or f"nominal-{cpi:g}cpi",
            date or _dt.date.today().isoformat(),
            nominal=True,
            notes=f"nominal {cpi:g} CPI",
        )

    def counts_to_mm(self, counts: np.ndarray) -> np.ndarray:
        """Apply ``A``: counts of shape (N, 2) (or (2,)) -> displacement in mm of the same shape."""
        return np.asarray(counts, dtype=float) @ self.matrix_mm_per_count.T

    def mm_to_counts(self, displacement_mm: np.ndarray) -> np.ndarray:
        """Inverse map ``A^-1 d`` (fractional counts), shape (N, 2) or (2,); used by simulators."""
        return np.asarray(displacement_mm, dtype=float) @ np.linalg.inv(self.matrix_mm_per_count).T

    @property
    def effective_cpi(self) -> tuple[float, float]:
        """Counts per inch along each sensor axis, ``25.4 / |A e_i|`` (``sensors.md`` §5.2)."""
        norms = np.linalg.norm(self.matrix_mm_per_count, axis=0)
        return float(MM_PER_INCH / norms[0]), float(MM_PER_INCH / norms[1])

    def to_dict(self) -> dict[str, object]:
        """Plain-data form for run manifests and calibration files."""
        return {
            "calibration_id": self.calibration_id,
            "date": self.date,
            "nominal": self.nominal,
            "matrix_mm_per_count": self.matrix_mm_per_count.tolist(),
            "notes": self.notes,
        }

    @classmethod
    def from_dict(cls, data: dict[str, object], *, where: str = "calibration") -> CountsCalibration:
        """Rebuild from :meth:`to_dict` output; unknown or missing keys are refused with their names."""
        expected = {"calibration_id", "date", "nominal", "matrix_mm_per_count", "notes"}
        unknown = set(data) - expected
        missing = {"calibration_id", "date", "matrix_mm_per_count"} - set(data)
        if unknown or missing:
            raise ConfigError(
                f"{where}: unknown keys {sorted(unknown)} / missing keys {sorted(missing)}, "
                f"expected keys {sorted(expected)}"
            )
        return cls(
            np.asarray(data["matrix_mm_per_count"], dtype=float),
            str(data["calibration_id"]),
            str(data["date"]),
            bool(data.get("nominal", False)),
            str(data.get("notes", "")),
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, CountsCalibration) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(self.content_hash())

    def content_hash(self) -> str:
        """SHA-256 (first 16 hex digits) of the canonical JSON form: runs reference calibrations by id and hash."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]
