"""The paper's printed numbers: its two hinges, their printed surfaces and conclusions, and its tables.

The numbers are transcribed from the paper's text; the sample tables ship as
``rsm/data/paper_table*.csv`` (values exactly as printed; the preload column of Table 4 is
in N although the paper labels it mm). ``rsm.paper`` compares them with a refit.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

ETA_THRESHOLD = 0.05
"""The paper's design target, Sec. V.A: "the loss factor had to be reduced to less than 0.05"."""


@dataclass(frozen=True)
class HingeCase:
    """One hinge of the paper: its table, its printed surface and printed errors."""

    name: str
    csv_name: str
    x_names: tuple[str, str]
    symbols: tuple[str, str]
    approx_column: str
    printed_coefficients: tuple[str, ...]
    printed_deviation_percent: tuple[str, ...]
    equation: str
    table: str
    printed_max_re_percent: float
    printed_min: float
    printed_max: float


GENERAL = HingeCase(
    name="general",
    csv_name="paper_table1_general_hinge.csv",
    x_names=("clearance_mm", "amplitude_N"),
    symbols=("Δr", "F_g"),
    approx_column="eta_rsm_table2",
    printed_coefficients=(
        "-0.10774",
        "-0.12748",
        "0.00275",
        "0.07342",
        "1.75806e-4",
        "-1.22277e-5",
        "0.40833",
        "-8.59694e-4",
        "1.42347e-7",
        "2.22867e-8",
        "-0.54167",
        "1.66667e-4",
        "1.11735e-6",
        "-6.66667e-10",
        "-1.45833e-11",
    ),
    printed_deviation_percent=(
        "0.407",
        "-0.712",
        "0.853",
        "-0.484",
        "0.109",
        "-0.164",
        "-0.024",
        "0.351",
        "-0.289",
        "0.035",
        "-0.180",
        "0.272",
        "-0.111",
        "-0.244",
        "0.164",
        "-0.034",
        "0.275",
        "-0.639",
        "0.512",
        "-0.093",
        "-0.223",
        "0.425",
        "-0.820",
        "0.855",
        "-0.312",
    ),
    equation="Eq. 6",
    table="Table 2",
    printed_max_re_percent=0.855,
    printed_min=0.0353,
    printed_max=0.1087,
)

MODIFIED = HingeCase(
    name="modified",
    csv_name="paper_table4_modified_hinge.csv",
    x_names=("preload_N", "amplitude_N"),
    symbols=("F_p", "F_g"),
    approx_column="eta_rsm_table5",
    printed_coefficients=(
        "-0.21797",
        "-1.06155e-4",
        "3.72353e-3",
        "6.24476e-7",
        "2.03960e-6",
        "-1.67340e-5",
        "-2.81333e-9",
        "-2.20367e-9",
        "-6.23765e-9",
        "3.10783e-8",
        "3.46667e-12",
        "4.13333e-12",
        "1.16327e-12",
        "5.95e-12",
        "-2.08667e-11",
    ),
    printed_deviation_percent=(
        "-0.422",
        "0.711",
        "-1.529",
        "1.503",
        "-0.456",
        "-1.246",
        "0.587",
        "-0.633",
        "0.654",
        "-0.278",
        "0.333",
        "0.073",
        "-0.038",
        "-0.445",
        "0.301",
        "0.190",
        "-0.428",
        "0.713",
        "-0.443",
        "0.094",
        "0.679",
        "-0.707",
        "1.140",
        "-0.902",
        "0.230",
    ),
    equation="Eq. 13",
    table="Table 5",
    printed_max_re_percent=1.529,
    printed_min=0.0160,
    printed_max=0.0733,
)

PRINTED_CLEARANCE_FOR_THRESHOLD_MM = 0.2248
"""Sec. V.A: for η < 0.05 "the clearance ... should be greater than 0.2248 mm"."""

PRINTED_TABLE7_ETA = {"general": 0.0659, "modified": 0.0160}
"""Table 7: η "calculated by substituting the parameters of the hinges into Eqs. (6) and (13)"."""

TABLE7_POINT = {"general": (0.0, 100.0), "modified": (0.0, 100.0)}
"""Where the project evaluates Table 7's η: zero clearance or preload and the 100 N pendulum
load of Sec. V.B (the paper does not say which parameters it substituted; this is a reading)."""

PRINTED_REDUCTION_PERCENT = {"min": 54.67, "max": 32.57, "table7": 75.72}


def half_unit(printed: str) -> float:
    """Return half a unit in the last printed digit of a number written as text.

    Example:
        >>> half_unit("1.75806e-4"), half_unit("0.00275")
        (5e-10, 5e-06)
    """
    mant, _, exp = printed.lower().partition("e")
    decimals = len(mant.partition(".")[2])
    return 0.5 * 10.0 ** (int(exp or 0) - decimals)


@contextmanager
def paper_table_path(csv_name: str) -> Iterator[Path]:
    """Yield a filesystem path to one of the shipped paper tables."""
    with resources.as_file(resources.files("rsm") / "data" / csv_name) as p:
        yield Path(p)
