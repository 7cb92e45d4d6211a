"""icrflow: exact grasp quality alpha*, 6D independent contact regions and an in-hand
rolling planner (type stubs; the reference is python/README.md)."""

import os
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
ArrayLike = npt.ArrayLike
PathLike = Union[str, "os.PathLike[str]"]

class IcrflowError(Exception):
    """A grasp or plan that cannot be computed (not force closure for ICRs, a margin above
    the grasp's alpha*, a scenario the planner refuses), with the CLI's message."""

class Object:
    """A rigid object: a closed, consistently oriented polygon mesh in its body frame, with
    its candidate contact points (SI units)."""

    @staticmethod
    def sphere(radius: float, segments: Tuple[int, int] = (72, 72)) -> "Object":
        """A UV sphere of `radius` (m), `segments = (longitude, latitude)` faces."""
    @staticmethod
    def ellipsoid(
        semi_axes: Tuple[float, float, float], segments: Tuple[int, int] = (72, 72)
    ) -> "Object":
        """An ellipsoid with semi-axes (a, b, c) (m) along x, y, z."""
    @staticmethod
    def mesh(path: PathLike) -> "Object":
        """Reads a closed mesh from an .stl or .obj file (FileNotFoundError if missing,
        ValueError if not a valid closed mesh)."""
    @staticmethod
    def from_arrays(
        vertices: ArrayLike,
        faces: Union[ArrayLike, Sequence[Sequence[int]]],
        name: str = "arrays",
    ) -> "Object":
        """From vertices (V, 3) and faces ((F, k) integer array or a list of polygons),
        counter-clockwise seen from outside (e.g. a trimesh.Trimesh's)."""
    @property
    def name(self) -> str: ...
    @property
    def vertices(self) -> FloatArray:
        """(V, 3), m."""
    @property
    def faces(self) -> List[List[int]]: ...
    @property
    def facet_points(self) -> FloatArray:
        """Spatial candidates: facet centroids, (m, 3)."""
    @property
    def facet_normals(self) -> FloatArray:
        """Outward unit normals of the facets, (m, 3)."""
    @property
    def section_points(self) -> FloatArray:
        """Planar candidates: the section through the centre of mass, (k, 3)."""
    @property
    def section_normals(self) -> FloatArray: ...
    @property
    def section_angles(self) -> FloatArray:
        """Radians in [0, 2 pi), (k,)."""
    @property
    def centre_of_mass(self) -> FloatArray:
        """(3,), m."""
    @property
    def volume(self) -> float: ...
    @property
    def max_radius(self) -> float:
        """Largest vertex distance from the centre of mass: the default rho."""
    @property
    def warnings(self) -> List[str]: ...

class Evaluation:
    """One grasp's quality (GraspProblem.evaluate)."""

    alpha_star: float
    epsilon: float
    force_closure: bool
    closure: Literal["force_closure", "origin_on_boundary", "origin_outside", "degenerate"]
    contacts: IntArray
    """Candidate indices, (n,)."""
    points: FloatArray
    """Candidate points, (n, 3)."""
    snap_distances: FloatArray
    """Distance from each given point to its candidate, (n,); 0 for indices."""
    hull_facets: int
    hull_normals: FloatArray
    """(hull_facets, dim)."""
    hull_offsets: FloatArray
    """(hull_facets,)."""
    limiting_facet: Optional[int]

class Region:
    """One contact's independent contact region."""

    contact: int
    indices: IntArray
    """Candidate indices, ascending, (m,)."""
    points: FloatArray
    """(m, 3)."""
    zones: int
    def __len__(self) -> int: ...

class BatchResult(TypedDict):
    alpha_star: FloatArray
    epsilon: FloatArray
    force_closure: BoolArray

class GraspProblem:
    """One object and contact model; contacts are (n, 3) float points (snapped to the
    nearest candidates) or (n,) integer candidate indices."""

    def __init__(
        self,
        obj: Object,
        friction: float,
        cone_edges: int = 8,
        space: Literal["spatial", "planar"] = "spatial",
        rho: Optional[float] = None,
    ) -> None: ...
    @property
    def object(self) -> Object: ...
    @property
    def space(self) -> Literal["spatial", "planar"]: ...
    @property
    def friction(self) -> float: ...
    @property
    def cone_edges(self) -> int: ...
    @property
    def rho(self) -> float: ...
    @property
    def dim(self) -> int: ...
    @property
    def candidates(self) -> FloatArray:
        """(k, 3): a contact index is a row."""
    @property
    def candidate_normals(self) -> FloatArray: ...
    def snap(self, points: ArrayLike) -> Tuple[IntArray, FloatArray]:
        """Nearest candidates of (n, 3) points: (indices, distances)."""
    def evaluate(self, contacts: ArrayLike) -> Evaluation:
        """alpha*, epsilon, force closure and the hull of one grasp."""
    def icrs(self, contacts: ArrayLike, alpha: float) -> List[Region]:
        """The ICRs with margin alpha, one per contact (IcrflowError if the grasp is not
        force closure or alpha exceeds its alpha*)."""
    def evaluate_batch(self, contacts: ArrayLike, threads: Optional[int] = None) -> BatchResult:
        """N grasps, (N, n, 3) points or (N, n) indices, on every core (GIL released)."""

class Plan:
    """An offline rolling plan (see python/README.md for the trajectory's arrays)."""

    summary: Dict[str, Any]
    trajectory: Dict[str, np.ndarray]
    switches: List[Dict[str, Any]]

def plan(config: Union[PathLike, Dict[str, Any]]) -> Plan:
    """Plans the scenario of a TOML config (path) or a dict shaped like one."""
