"""The orientation results of a pose run read by the calliper tilt gauge (``dissertation_pose`` alpha/beta):
AP_a/AP_b and RP_a/RP_b per pose with U (ISO 9283 7.2.1, 7.2.2), and their uncertainty budget.

Every number comes from :mod:`bench.metrology.orientation`; this module lays it out as document blocks, rounded by
its uncertainty (:mod:`bench.metrology.formatting`).
"""

from __future__ import annotations

from bench.metrology.formatting import format_measured, format_uncertainty, pose_label
from bench.metrology.orientation import tilt_standard_uncertainty_deg
from bench.reports.blocks import Paragraph, Table

__all__ = ["orientation_blocks", "orientation_headline"]

_ANGLE_WORDS = {"a": "alpha (about x)", "b": "beta (about y)", "c": "gamma (about z)"}


def orientation_blocks(report) -> tuple:
    """The results table and the budget table of ``report.orientation`` (empty without tilt readings)."""

    if not report.orientation:
        return ()
    k = f"{report.coverage_factor:g}"
    gauge = report.tilt_gauge
    angles = [f.angle for f in report.orientation[0].figures]
    header = ("Pose", "n", *(h for a in angles for h in (f"Command {a} (°)", f"AP_{a} ± U (°)", f"RP_{a} ± U (°)")))
    rows = tuple(
        (
            pose_label(r.pose, r.conditions),
            str(r.figures[0].n),
            *(
                cell
                for f in r.figures
                for cell in (
                    f"{f.commanded_deg:g}",
                    format_measured(f.ap_deg, f.u_ap_deg, signed=True),
                    format_measured(f.rp_deg, f.u_rp_deg),
                )
            ),
        )
        for r in report.orientation
    )
    words = ", ".join(_ANGLE_WORDS.get(a, a) for a in angles)
    budget = (
        (
            "one depth reading u(h)",
            f"{format_uncertainty(gauge.u_depth_mm)} mm",
            f"resolution {gauge.resolution_mm:g} mm (δ/√12) and MPE ± {gauge.mpe_mm:g} mm (rectangular)",
        ),
        ("hole spacing u(s)", f"{format_uncertainty(gauge.u_spacing_mm)} mm", f"s = {gauge.spacing_mm:g} mm"),
        (
            "tilt from two depths u(θ) at 0°",
            f"{tilt_standard_uncertainty_deg(0.0, gauge):.3f}°",
            "u²(θ) = [cos²θ / s]²·2u²(h) + [sinθ cosθ / s]²·u²(s)",
        ),
        ("tilt from two depths u(θ) at 20°", f"{tilt_standard_uncertainty_deg(20.0, gauge):.3f}°", "as above"),
        (
            "play-bias correction",
            f"{gauge.u_bias_deg:.3f}°",
            "none applied"
            if gauge.bias_deg == 0
            else f"{gauge.bias_deg:+g}° subtracted, measured at home with the actuators locked",
        ),
        ("scatter of the mean", "S/√n per pose", "Type A, from the readings"),
    )
    return (
        Table(
            "orientation",
            header,
            rows,
            f"Orientation accuracy and repeatability per pose, {words}, from the "
            f"calliper tilt readings (ISO 9283 7.2.1, 7.2.2; U: k = {k})",
        ),
        Paragraph(
            "AP = mean − command (signed); RP = 3 S. U(AP) = k·√(S²/n + u²(θ) + u²(bias)), the calliper terms "
            "kept whole as they are systematic over the run; U(RP) = k·3S/√(2(n − 1)). The tilt is the "
            "gradient of two depths through holes s apart, θ = atan(Δh / s)."
        ),
        Table(
            "orientation_budget",
            ("Component", "Standard uncertainty", "Source"),
            budget,
            "Orientation uncertainty budget (one tilt reading)",
        ),
    )


def orientation_headline(report) -> tuple:
    """Page 1's orientation headline of a run with tilt readings: per angle, the worst and mean |AP| and RP over
    the poses (:func:`bench.metrology.orientation_tables.orientation_summary`); empty without tilt readings."""
    from bench.metrology.orientation_tables import orientation_summary

    if not report.orientation:
        return ()
    rows = tuple(
        (
            _ANGLE_WORDS.get(angle, angle),
            str(len(report.orientation)),
            f"{format_measured(s['worst_abs_AP_deg'], s['U_AP_deg'])} ({s['worst_AP_pose']})",
            f"{s['mean_abs_AP_deg']:.2f}",
            f"{format_measured(s['worst_RP_deg'], s['U_RP_deg'])} ({s['worst_RP_pose']})",
            f"{s['mean_RP_deg']:.2f}",
        )
        for angle, s in orientation_summary(report.orientation).items()
    )
    return (
        Table(
            "orientation_headline",
            ("Angle", "Poses", "Worst |AP| ± U (°)", "Mean |AP| (°)", "Worst RP ± U (°)", "Mean RP (°)"),
            rows,
            f"Orientation headline from the calliper tilt readings (U: k = {report.coverage_factor:g})",
        ),
    )
