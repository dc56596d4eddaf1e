"""Type stubs of the native module ``tfs._tfs`` (re-exported by ``tfs``)."""

import os
from typing import Any, Literal, Mapping, Sequence, Union

import numpy as np
import numpy.typing as npt

from ._results import Comparison

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike]
Records = Union["Record", PathLike, Sequence[Union["Record", PathLike]]]

# The closed sets of values some keywords take (editors and type checkers list them).
Method = Literal["tfs", "sindy"]
IdentifyOffsets = Literal["auto", "keep", "remove", "constant-term"]
ModelOffsets = Literal["auto", "keep", "remove"]
Clipped = Literal["error", "warn", "allow"]
TruthLaw = Literal["surrogate", "truss"]
TruthSpec = Literal["kresling", "kresling:surrogate", "kresling:truss"]

__version__: str

class Record:
    """One measurement record: a uniform time axis ``t`` (s) and named columns."""

    def __init__(
        self,
        x: ArrayLike,
        *,
        t: ArrayLike | None = None,
        dt: float | None = None,
        t0: float = 0.0,
        inputs: Mapping[str, ArrayLike] | None = None,
        dofs: Sequence[str] | None = None,
        name: str = "record",
    ) -> None: ...
    @staticmethod
    def from_csv(path: PathLike) -> Record: ...
    def to_csv(self, path: PathLike) -> None: ...
    @property
    def t(self) -> npt.NDArray[np.float64]: ...
    @property
    def dt(self) -> float: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def source(self) -> str: ...
    def __getitem__(self, name: str) -> npt.NDArray[np.float64]: ...
    def __contains__(self, name: str) -> bool: ...
    def __len__(self) -> int: ...

class Model:
    """An identified model ``x'' = sum(coef * term(x, x', u))``, one equation per DOF."""

    @property
    def dofs(self) -> list[str]: ...
    @property
    def inputs(self) -> list[str]:
        """The inputs the model was identified with (``simulate``/``predict`` take them by name
        or in this order; those whose terms were dropped are ignored)."""
    @property
    def used_inputs(self) -> list[str]:
        """The inputs the equations use."""
    @property
    def verdict(self) -> str | None:
        """``refit`` only: whether the geometric-mean R-MSE over the records fell, in one sentence."""
    @property
    def improved(self) -> bool | None:
        """``refit`` only: True when the geometric-mean R-MSE fell, False when it rose."""
    @property
    def method(self) -> str: ...
    @property
    def trace(self) -> dict[str, Any]: ...
    @property
    def report(self) -> dict[str, Any] | None: ...
    @property
    def coefficients(self) -> dict[str, dict[str, float]]: ...
    @property
    def intervals(self) -> dict[str, dict[str, tuple[float, float]]]: ...
    @property
    def terms(self) -> list[str]: ...
    @property
    def coefficient_array(self) -> npt.NDArray[np.float64]: ...
    def equations(self) -> list[str]: ...
    def print(self) -> None: ...
    def simulate(
        self,
        t: ArrayLike,
        u: ArrayLike | Mapping[str, ArrayLike] | None = None,
        x0: Sequence[float] | None = None,
        v0: Sequence[float] | None = None,
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def predict(
        self,
        x: ArrayLike,
        v: ArrayLike,
        u: ArrayLike | Mapping[str, ArrayLike] | None = None,
    ) -> npt.NDArray[np.float64]: ...
    def compare(
        self, records: Records, *, offsets: ModelOffsets = "auto", clipped: Clipped = "error"
    ) -> Comparison: ...
    def refit(
        self,
        records: Records,
        add: Sequence[str] = (),
        *,
        until_clean: int | None = None,
        refine: bool = False,
        validate: Records | None = None,
        offsets: ModelOffsets = "auto",
        clipped: Clipped = "error",
    ) -> Model: ...
    @staticmethod
    def from_terms(
        coefficients: Mapping[str, Mapping[str, float]],
        *,
        dofs: Sequence[str] | None = None,
        method: str = "from_terms",
    ) -> Model:
        """A model from ``{dof: {term: coefficient}}`` (what ``model.coefficients`` gives)."""
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> Model: ...
    def save(self, path: PathLike) -> None: ...
    @staticmethod
    def load(path: PathLike) -> Model: ...

def identify(
    records: Records,
    library: str | None = None,
    *,
    method: Method = "tfs",
    dofs: Sequence[str] | None = None,
    threshold: float | None = None,
    refine: bool = False,
    validate: Records | None = None,
    tie: bool | None = None,
    masses: str = "equal",
    offsets: IdentifyOffsets = "auto",
    clipped: Clipped = "error",
) -> Model: ...
def load(path: PathLike) -> Model: ...
def diagnose(
    model: Model,
    records: Records,
    *,
    alpha: float = 0.01,
    min_share: float = 0.02,
    offsets: ModelOffsets = "auto",
    clipped: Clipped = "error",
) -> dict[str, Any]: ...
def basin(
    model: Model | None = None,
    *,
    grid: tuple[int, int] = (200, 200),
    x: tuple[float, float] = (0.0, 2.0),
    v: tuple[float, float] = (-3.0, 3.0),
    truth: TruthSpec | None = None,
    cell: Mapping[str, float] | None = None,
    dt: float = 0.01,
    t_max: float = 100.0,
    search: tuple[float, float] | None = None,
) -> dict[str, Any]: ...
def med(
    model: Model | None = None,
    *,
    truth: TruthSpec | None = None,
    cell: Mapping[str, float] | None = None,
    grid: tuple[int, int] = (200, 200),
    x: tuple[float, float] = (0.0, 2.0),
    v: tuple[float, float] = (-3.0, 3.0),
    from_state: int = 1,
    to_state: int = 2,
) -> dict[str, float]: ...
def kresling(
    *,
    a0: float = 1.6,
    c0: float = 1.0,
    gamma0: float = 30.0,
    ka: float = 9.30,
    kb: float = 9.30,
    mass: float = 1.0,
    damping: float = 2.0,
) -> dict[str, Any]: ...
def simulate_kresling(
    *,
    gamma0: float = 30.0,
    excitations: Sequence[str] = ("sweep:0.05:1.5:4",),
    duration: float = 100.0,
    dt: float = 0.005,
    ramp: float = 2.0,
    snr_db: float | None = None,
    pink: bool = False,
    seed: int = 1,
    truth: TruthLaw | None = None,
) -> list[Record]: ...
def simulate_chain(
    *,
    gamma0: Sequence[float] = (20.0, 28.5),
    excitations: Sequence[str] | None = None,
    duration: float | None = None,
    dt: float = 0.005,
    ramp: float = 2.0,
    snr_db: float | None = None,
    pink: bool = False,
    seed: int = 1,
    truth: TruthLaw | None = None,
) -> list[Record]: ...
