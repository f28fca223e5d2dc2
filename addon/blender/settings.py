"""Each tool's settings as one dataclass: the add-on's side of the core's `*Params` structs.

Fields are named, nested and defaulted as the core's (`shapesmith_native.default_settings(tool)`
returns the same dict, `blender_tests/test_settings.py` holds them equal); `as_native()` is
the `settings` argument of the tool's native call. The panel's properties take their
`default=` from these, `scripts/batch.py` its flags' defaults, and one function per tool
below reads the panel's properties into the dataclass, so an option is added once here, once
in the core's struct, and the defaults cannot drift between panel, batch and core. No bpy
import: the properties module reads the defaults at registration."""

from dataclasses import asdict, dataclass, field
from typing import List, Optional, Tuple


class NativeSettings:
    def as_native(self):
        """The dict the native call takes as `settings` (nested dataclasses as dicts)."""
        return asdict(self)


# --- Analyze Rig: `AnalysisParams` ---


@dataclass
class SymmetrySettings(NativeSettings):
    """`SymmetryParams`: the mirror test of symmetric pairs and antagonists (method, section 0)."""

    pair_tolerance: float = 0.25
    antagonist_iou: float = 0.6
    mu: float = 0.3
    use_names: bool = True


@dataclass
class AnalyzeSettings(NativeSettings):
    axis: int = 0
    mirror_tolerance: float = 1e-3
    symmetry: SymmetrySettings = field(default_factory=SymmetrySettings)


# --- Pack Expressions: `PackingParams` (the refinements and the stored results are the rig's
# data, passed beside the settings) ---


@dataclass
class PackSettings(NativeSettings):
    mu: float = 0.3
    a: float = 0.5
    beta: float = 0.0
    max_expressions: Optional[int] = None
    symmetric: bool = True
    axis: int = 0
    mirror_tolerance: float = 1e-3
    pair_tolerance: float = 0.25
    antagonist_iou: float = 0.6
    antagonist_cosine: float = -0.5
    fewest: bool = False
    time_limit: Optional[float] = None
    collision_conflicts: bool = True
    collision_tolerance: float = 0.11
    occlusion_conflicts: bool = True
    occlusion_keep: float = 0.5
    camera_direction: Tuple[float, float, float] = (0.0, -1.0, 0.0)


# --- Place Landmarks: `LandmarkParams` (cameras and allowed vertices are data) and Score
# Layout: `ScoreParams` (the extra poses are data) ---


@dataclass
class LandmarkSettings(NativeSettings):
    epsilon: float = 0.5
    alpha: float = 0.5
    gamma: float = 0.5
    rays: int = 64
    symmetric: bool = False
    axis: int = 0
    mirror_tolerance: float = 1e-3
    max_per_shape: int = 2
    radius: float = 0.03
    share_limit: float = 0.1
    min_visibility: float = 0.0
    seed: int = 0
    time_limit: Optional[float] = None
    landmarks: Optional[int] = None
    target_error: Optional[float] = None
    criterion: str = "a"
    pool_epsilon: float = 0.3
    pool_visibility: float = 0.25
    noise: float = 0.002
    curve_to: int = 68
    reuse_visibility: bool = True


@dataclass
class ScoreSettings(NativeSettings):
    noise: float = 0.002
    seed: int = 0
    random_mixes: int = 50


# --- Transfer Shape Keys: `TransferShapesParams` ---


@dataclass
class VirtualEdgeSettings(NativeSettings):
    """`VirtualEdgeParams`: springs across lips and lids (Li, Shen & Liu 2023)."""

    tau_d: float = 0.015
    tau_r: float = 4.0
    max_per_vertex: int = 3


@dataclass
class ContactSettings(NativeSettings):
    """`ContactParams`: the contact solve after each shape's solve (method, section 3)."""

    distance: float = 0.25


@dataclass
class DeformationSettings(NativeSettings):
    """`TransferParams`; None for `virtual_edges` or `contact` turns that stage off."""

    virtual_edges: Optional[VirtualEdgeSettings] = field(default_factory=VirtualEdgeSettings)
    edge_weight: float = 3.0
    static_fraction: float = 1e-5
    align_rotation: bool = True
    contact: Optional[ContactSettings] = None


@dataclass
class PersonaliseSettings(NativeSettings):
    """`PersonaliseParams`: the fit to training expressions (Li, Weise & Pauly 2010)."""

    beta_reg: float = 1.0
    refine_weights: bool = False


@dataclass
class TransferSettings(NativeSettings):
    transfer: DeformationSettings = field(default_factory=DeformationSettings)
    personalise: PersonaliseSettings = field(default_factory=PersonaliseSettings)
    compare_plain: bool = False
    measure_penetration: bool = True


# --- Wrap: `WrapParams` (the fit) and `CarryParams` (the keys onto the character) ---


@dataclass
class FitSettings(NativeSettings):
    """`FitParams`: the non-rigid fit (Amberg et al. 2007)."""

    stiffness: List[float] = field(default_factory=lambda: [100.0, 50.0, 20.0, 10.0, 5.0, 2.0, 1.0, 0.5])
    iterations: int = 3
    landmark_weight: float = 100.0
    max_angle_degrees: float = 60.0
    max_distance: float = 0.1
    rim_weight: float = 1.0
    tolerance: float = 1e-4


@dataclass
class WrapSettings(NativeSettings):
    fit: FitSettings = field(default_factory=FitSettings)
    align_only: bool = False
    ignore_symmetry: bool = False


@dataclass
class CarrySettings(NativeSettings):
    static_fraction: float = 1e-4
    anchor_length: float = 2.0
    max_angle_degrees: float = 60.0
    collision_pass: bool = True
    collision_margin: float = 0.25
    collision_stiffness: float = 100.0
    collision_tolerance: float = 1e-3
    symmetrize: bool = True


# --- Solve Performance: `PerformanceParams` (the start pose is the head's placement, data) ---


@dataclass
class PerformanceSettings(NativeSettings):
    smoothing: float = 1.0
    noise_points: float = 1e-3
    noise_pixels: float = 1.0
    huber: Optional[float] = 3.0
    solve_scale: bool = False
    iterations: int = 30
    rigid_fraction: float = 0.05


# The `default_settings(tool)` name of each dataclass.
TOOLS = {
    "analyze": AnalyzeSettings,
    "pack": PackSettings,
    "landmarks": LandmarkSettings,
    "score": ScoreSettings,
    "transfer": TransferSettings,
    "virtual_edges": VirtualEdgeSettings,
    "wrap": WrapSettings,
    "carry": CarrySettings,
    "performance": PerformanceSettings,
}


# --- The panel's properties (or batch's flags of the same names) read into each tool's settings ---


def analyze_settings(scene):
    """Analyze Rig's settings from the scene's Rig panel."""
    props = scene.shapesmith
    return AnalyzeSettings(axis=int(props.symmetry_axis), symmetry=SymmetrySettings(use_names=props.pair_by_name))


def pack_settings(props, axis=0, time_limit=None):
    """Pack Expressions' settings from an object's Pack panel (`obj.shapesmith.pack`), with
    the scene's symmetry axis and the preferences' solver time limit."""
    return PackSettings(
        mu=props.mu,
        a=props.a,
        beta=props.beta,
        max_expressions=props.max_expressions if props.limit_expressions else None,
        symmetric=props.symmetric,
        axis=axis,
        antagonist_cosine=props.antagonist_cosine,
        fewest=props.fewest,
        time_limit=time_limit,
        collision_conflicts=props.collision_conflicts,
        collision_tolerance=props.collision_tolerance,
        occlusion_conflicts=props.occlusion_conflicts,
        occlusion_keep=props.occlusion_keep,
    )


def landmark_settings(props, axis=0):
    """Place Landmarks' settings from the scene's Landmarks panel
    (`scene.shapesmith.landmarks`); the count or the target error only when its *Add for
    Reconstruction* asks for it."""
    return LandmarkSettings(
        epsilon=props.epsilon,
        alpha=props.alpha,
        gamma=props.gamma,
        rays=props.rays,
        symmetric=props.symmetric,
        axis=axis,
        max_per_shape=props.max_per_shape,
        radius=props.radius,
        landmarks=props.landmarks if props.design == "COUNT" else None,
        target_error=props.target_error if props.design == "TARGET" else None,
    )


def transfer_settings(props):
    """Transfer Shape Keys' settings from the Transfer panel (`scene.shapesmith.transfer`) or
    from `batch.py transfer`'s flags, which have the properties' names."""
    return TransferSettings(
        transfer=DeformationSettings(
            virtual_edges=VirtualEdgeSettings(tau_d=props.tau_d, tau_r=props.tau_r) if props.virtual_edges else None,
            edge_weight=props.edge_weight,
            contact=ContactSettings(distance=props.contact_distance) if props.contact else None,
        ),
        personalise=PersonaliseSettings(beta_reg=props.beta_reg, refine_weights=props.refine_weights),
        compare_plain=props.compare_plain,
    )


def performance_settings(props):
    """Solve Performance's settings from the Performance panel (`scene.shapesmith_performance`)
    or from `batch.py solve`'s flags of the same names."""
    return PerformanceSettings(smoothing=props.smoothing, solve_scale=props.solve_scale)
