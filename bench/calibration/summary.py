"""The text ``bench calibrate`` prints and the window shows for a stored kinematic calibration: parameters and
uncertainties, the fit and its observability, the in-sample error, the campaign (the robot's scatter apart from
the instrument's figure, the search, the plan for the target gain)."""

from __future__ import annotations

from typing import Any

__all__ = ["summary_lines"]


def summary_lines(identified: Any) -> list[str]:
    """The text ``bench calibrate`` prints (and the window shows) for ``identified``, a
    :class:`bench.calibration.identify.IdentifiedRun`: parameters, uncertainties, observability."""
    from bench.metrology.formatting import format_pair

    result, record, params = identified.result, identified.record, identified.params
    obs = result.observability
    lines = [
        f"{record.name} v{record.version} (id {record.id}) from run {identified.run_id}: "
        f"{identified.n_measurements} poses, {len(result.names)} free parameters",
        f"{'parameter':<18} {'value':>12} {'std. unc.':>12}  unit",
    ]
    for name, value, std, unit in zip(result.names, result.values, result.uncertainty, result.units):
        shown, u = format_pair(value, std, signed=True)  # to the uncertainty's 2 significant digits, as the report
        lines.append(f"{name:<18} {shown:>12} {u:>12}  {unit}")
    below = params.get("approach_from_below_mm")
    if below is not None:
        lines.append(
            f"poses approached from {below:g} mm below (the legs' backlash is in the identified offsets for that "
            "approach: runs commanded by this calibration should approach the same way)"
            if below
            else "poses approached directly (the legs' backlash, whose sign follows the pose before, is not modelled)"
        )
    if result.fit == "map":
        source = params.get("prior") or {}
        lines.append(
            f"fit: maximum a posteriori, prior: {source.get('name', 'the tolerances')}; fixed by the prior "
            f"(the data did not inform them): {', '.join(result.prior_only) or 'none'}"
        )
        lines.append(
            f"data part: condition number {obs.condition_number:.3g} (the prior holds its weak directions; "
            f"refused when the data inform under half the parameters), O1 {obs.o1:.4g}, reduced chi2 "
            f"{result.reduced_chi2:.2f} over {result.degrees_of_freedom:.1f} degrees of freedom"
        )
    else:
        lines.append(
            f"condition number {obs.condition_number:.1f} (limit 100), O1 {obs.o1:.4g}, reduced chi2 "
            f"{result.reduced_chi2:.2f}"
        )
    lines.append(
        f"mean position error on the calibration poses (in-sample): before {params['ap_before_mm']:.3f} "
        f"mm, after {params['ap_after_mm']:.3f} mm"
    )
    lines += _campaign_lines(params)
    if "command_resolution_mm" in params:
        steps = (
            "fine steps (0.01 deg references)"
            if params.get("servo_references") == "fine_centidegree"
            else f"byte steps ({params['servo_mapping']['name']} mapping)"
        )
        lines.append(
            f"command resolution: the servos' {steps} move these poses by "
            f"{params['command_resolution_mm']:.3f} mm on average, which no compensation goes below"
        )
    return lines


def _campaign_lines(params: dict) -> list[str]:
    """The campaign's part of the summary: the robot's scatter apart from the instrument's figure, the search, the
    plan for the target gain (cycles per pose, robot time) and the gain the play lets a validation show."""
    campaign, lines = params.get("campaign"), []
    search = params.get("search")
    if search:
        lines.append(
            f"search: {search['starts']} starts from the prior, kept start {search['kept_start']} "
            "(lowest MAP objective; no other plausible solution differs beyond 5 standard uncertainties)"
        )
    if search and search.get("profile_widened"):
        lines.append(
            "profile likelihood: the objective rises slower than its linearisation along "
            + ", ".join(f"{name} (u x {ratio:.2f})" for name, ratio in search["profile_widened"].items())
            + ": those uncertainties are the k = 2 profile interval's wider side over 2"
        )
    ambiguity = params.get("ambiguity")
    if ambiguity:
        lines.append(
            f"ambiguous: a second solution as plausible differs in {', '.join(ambiguity['widened'])} yet predicts "
            f"the same positions within this one's k = 2 uncertainty at {ambiguity['workspace_poses']} workspace "
            f"poses (at most {ambiguity['workspace_difference_mm']:.3f} mm apart): stored with those parameters' "
            "uncertainties widened to cover it"
        )
    if not campaign:
        return lines
    cycles = campaign["cycles_per_pose"]
    scatter = campaign["scatter_mm"]
    shown = (
        "not measured (one reading per pose)"
        if scatter[0] is None
        else ", ".join(f"{s:.3f}" for s in scatter) + f" mm per axis ({campaign['scatter_dof']} degrees of freedom)"
    )
    lines.append(
        f"robot scatter of one reading: {shown}; instrument: {campaign['instrument_uncertainty_mm']:.3g} mm "
        f"(stated, the floor); {min(cycles)}-{max(cycles)} cycles per pose, so each pose's mean is "
        f"uncertain by {', '.join(f'{u:.3f}' for u in campaign['mean_uncertainty_mm'])} mm (RMS per axis)"
    )
    if campaign.get("left_out_poses"):
        lines.append(
            "left out, erratic (a scatter beyond the other poses', F-test at 1e-6; their means measure no "
            "geometry): the poses visited "
            + ", ".join(f"#{i + 1}" for i in campaign["left_out_poses"])
            + " first-visit order"
        )
    plan, per_sample = campaign.get("plan"), campaign.get("seconds_per_sample")
    if plan:
        poses = len(cycles)

        def robot_time(n):
            clock = " by the simulator's clock" if params.get("simulated") else ""
            return "" if per_sample is None else f", {n * poses * per_sample / 60:.0f} min of robot time{clock}"

        wanted = plan["calibration_cycles"]
        lines.append(
            f"plan for {plan['target_gain']:g}x over the {plan['geometric_error_mm']:.3f} mm the geometry explains: "
            + (f"{wanted} cycles per pose{robot_time(wanted)}" if wanted else "out of reach by cycles")
            + (
                f"; a validation run needs {plan['validation_cycles']} cycles per pose to show it (the measured "
                f"scatter, {plan['scatter_mm']:.2f} mm a reading over the axes)"
                if plan["validation_cycles"]
                else ""
            )
        )
    return lines
