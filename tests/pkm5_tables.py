"""Loaders for the pkm5 fixture tables (tests/data/pkm5, copied from shared/reference/pkm5.md §6)."""

from pathlib import Path

import numpy as np
import pandas as pd

DATA = Path(__file__).parent / "data" / "pkm5"
LENGTHS = [f"L{i}_mm" for i in range(1, 7)]
IK_TABLES = {"translation": "table_a8_translation.csv", "alpha": "table_a9_alpha.csv", "beta": "table_a10_beta.csv"}
FK_TABLES = {
    "translation": "table_a15_fk_translation.csv",
    "alpha": "table_a16_fk_alpha.csv",
    "beta": "table_a17_fk_beta.csv",
}


def poses_from(df: pd.DataFrame, mode: str, prefix: str = "") -> np.ndarray:
    """(N, 5) poses in mm and rad from a table's x, y, z and mode-angle columns (degrees)."""
    poses = np.zeros((len(df), 5))
    poses[:, :3] = df[[f"{prefix}x_mm", f"{prefix}y_mm", f"{prefix}z_mm"]].to_numpy(float)
    if mode != "translation":
        poses[:, 3 if mode == "alpha" else 4] = np.radians(df[f"{prefix}{mode}_deg"].to_numpy(float))
    return poses


def ik_table(mode: str):
    df = pd.read_csv(DATA / IK_TABLES[mode])
    return df, poses_from(df, mode)


def fk_table(mode: str):
    df = pd.read_csv(DATA / FK_TABLES[mode])
    return df, poses_from(df, mode, "true_")
