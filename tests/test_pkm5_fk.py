"""FK of the 5-DOF PKM: least squares (production) and the dissertation's Newton-Raphson (parity)."""

import numpy as np
import pytest
from pkm5_tables import LENGTHS, fk_table, ik_table

from motion import pkm5

ALL_MODES = ("constant-orientation", "alpha", "beta")


def test_full_retraction_anchor():
    """001 Table I lengths at full retraction (184 x4, 192 x2) -> 001 §IV.A pose (87.82, 0, 295.83), 0.005 mm."""
    result = pkm5.forward_kinematics([184, 184, 184, 184, 192, 192])
    np.testing.assert_allclose(result.pose[0], [87.82, 0, 295.83, 0, 0], atol=0.005)
    assert result.converged[0] and result.mode[0] == "translation"


def test_home_pose():
    """Home = 5 mm stroke on every leg (000 §8.3) -> (88.649, 0, 300.937) (pkm5.md §2.6)."""
    result = pkm5.forward_kinematics(pkm5.DEFAULT_GEOMETRY.home_lengths_mm)
    np.testing.assert_allclose(result.pose[0, :3], [88.649, 0, 300.937], atol=0.0005)


def test_round_trip_10k_random_reachable_poses():
    poses = pkm5.sample_reachable(10_000, kinds=ALL_MODES, seed=2024)
    assert {int(p[3] != 0) + 2 * int(p[4] != 0) for p in poses} == {0, 1, 2}
    result = pkm5.forward_kinematics(pkm5.inverse_kinematics(poses).lengths_mm)
    assert result.converged.all()
    assert np.abs(result.pose[:, :3] - poses[:, :3]).max() < 1e-9
    assert np.degrees(np.abs(result.pose[:, 3:] - poses[:, 3:])).max() < 1e-9
    assert result.residual_mm.max() < 1e-9


@pytest.mark.parametrize("mode, tolerance_mm", [("translation", 0.018), ("alpha", 0.032), ("beta", 0.27)])
def test_rounded_table_lengths(mode, tolerance_mm):
    """Lengths rounded to 0.01 mm (CAD precision) give pose errors up to 0.018 mm (translation), 0.032 mm (alpha)
    and 0.265 mm (beta, the ill-conditioned pose of Table A.10 at beta = 20.18 deg), pkm5.md §4.3."""
    df, poses = ik_table(mode)
    result = pkm5.forward_kinematics(df[LENGTHS].to_numpy(), mode=mode)
    error = np.abs(result.pose[:, :3] - poses[:, :3]).max()
    assert error <= tolerance_mm
    assert result.converged.all()
    assert result.residual_mm.max() < 0.01


def test_modes_detected_from_lengths():
    modes = pkm5.detect_mode(
        [[200, 200, 210, 210, 205, 205], [200, 201, 210, 210, 205, 205], [200, 200, 210, 210, 205, 206]]
    )
    assert modes.tolist() == ["translation", "beta", "alpha"]


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_newton_raphson_parity_with_tables_a15_a17(mode):
    """pkm5.md §4.2: with lengths from the IK at the true pose rounded to 0.01 mm and the printed guesses, the NR
    reproduces the "Converged" columns within 0.09 and the iteration counts, except the rows the reference lists:
    A.15 rows 5 and 6 diverge (their printed guesses cannot be what was run); A.16 rows 5, 25 and A.17 rows 6, 9, 25
    converge with the re-run counts given there."""
    df, poses = fk_table(mode)
    lengths = np.round(pkm5.inverse_kinematics(poses, check_limits=False).lengths_mm, 2)
    brackets = pkm5.bracket_vectors(poses)
    columns = [c.removeprefix("guess_") for c in df.columns if c.startswith("guess_")]
    for i, row in df.iterrows():
        kwargs = {}
        if mode != "translation":
            kwargs = {
                "brackets": {k: v[i] for k, v in brackets.items()},
                "gradient": np.tan(np.radians(row[f"true_{mode}_deg"])),
            }
        result = pkm5.forward_kinematics_nr(
            lengths[i, [0, 2, 4]], row[[f"guess_{c}" for c in columns]].to_numpy(float), mode=mode, **kwargs
        )
        rerun = row["rerun"]
        if rerun == "does not converge":
            assert not result.converged, f"row {row['row']}"
            continue
        expected_iterations = int(rerun.split()[-2]) if rerun.startswith("converges") else int(row["iterations"])
        assert result.converged
        assert result.iterations == expected_iterations, f"row {row['row']}"
        converged = row[[f"converged_{c}" for c in columns]].to_numpy(float)
        assert np.abs(result.solution - converged).max() <= 0.09, f"row {row['row']}"


@pytest.mark.parametrize(
    "mode, lengths, brackets, gradient, expected",
    [
        # pkm5.md §4.4: the example inputs of the FK scripts 000 App. B.3.1-B.3.3, solved from a neutral guess
        ("translation", (216.78, 240.5, 204.12), None, None, (179.871, -47.249, 293.728, 51.109, 44.553, 103.384)),
        (
            "alpha",
            (210.18, 206.49, 216.33),
            {"cd1": (45.7182, 36.8625), "cd3": (38.6652, 44.2041), "cd5": (18.6792, 19.5535)},
            -0.1763,
            (111.297, -23.680, 312.354, -9.9985, 69.0669, 59.1821, 97.1643),
        ),
        (
            "beta",
            (245.97, 227.47, 234.49),
            {"cd1": (34.9941, 47.1637), "cd3": (33.8522, 47.9899)},
            -0.2178,
            (161.565, 37.869, 323.734, -12.2871, 49.6499, 55.1300, 80.7064),
        ),
    ],
)
def test_newton_raphson_worked_examples(mode, lengths, brackets, gradient, expected):
    guess = [150, 0, 300] + ([0] if mode != "translation" else []) + [60, 60, 90]
    result = pkm5.forward_kinematics_nr(lengths, guess, mode=mode, brackets=brackets, gradient=gradient)
    assert result.converged
    np.testing.assert_allclose(result.solution, expected, atol=6e-4)


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_a_small_batch_starts_from_the_seed_the_k_d_tree_finds(mode):
    # up to 64 targets are matched to the seed table by brute force (no scipy.spatial import); the tree, which
    # larger batches query, must give the same nearest seed to every target
    from motion.pkm5 import fk

    starts, lengths = fk._seed_table(mode, pkm5.DEFAULT_GEOMETRY)
    rng = np.random.default_rng(7)
    targets = lengths[rng.integers(0, len(lengths), 64)] + rng.normal(0, 2.0, (64, 6))
    assert fk._BRUTE_FORCE_MAX_TARGETS == len(targets)
    np.testing.assert_array_equal(
        fk._nearest_seed(targets, mode, pkm5.DEFAULT_GEOMETRY),
        fk._seed_tree(mode, pkm5.DEFAULT_GEOMETRY).query(targets)[1],
    )
