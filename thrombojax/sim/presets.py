"""Dataset presets of the built-in solver: BendVessel, ClotEntry and tiny versions for tests.

Units are scaled: length = nominal vessel radius, density 1, clot Young's modulus ~1. Every
``*_range`` is a closed interval ``(low, high)`` from which each simulation draws uniformly
(``generate.draw_case``); the drawn values are stored as simulation attributes.
"""

from __future__ import annotations

import dataclasses

from thrombojax.errors import ConfigError
from thrombojax.study import DATASETS

__all__ = ["Preset", "PRESETS", "get_preset"]


@dataclasses.dataclass(frozen=True)
class Preset:
    """A dataset recipe.

    Attributes:
        name: preset name; kind: ``"bend"`` (one bent tube, rotated copies) or ``"tortuous"``
            (a random vessel per simulation).
        n_sims: simulations in the dataset; n_frames: frames after the initial one.
        study: the study's dataset this preset makes (``bendvessel`` or ``clotentry``: its
            Abaqus time and skipped frames, :data:`thrombojax.study.DATASETS`).
        radius: nominal (inlet) vessel radius.
        leg_in, leg_out, bend_radius, bend_angle_deg: bent tube (kind "bend").
        leg_out_range, bend_radius_range, bend_angle_range: None (default: every simulation
            has the one tube above) or ``(low, high)``: each simulation of a bend draws its own
            value (stream ``[seed, index, 1]``; a new vessel shape per simulation, same node
            count). Such presets run one simulation at a time (``batch_size`` 1: the cases of
            a batch share one vessel).
        rotation_step_deg, rotation_axis: simulation i is rotated by ``i * step`` about the axis.
        length, min_bend_radius, radius_end, wobble: tortuous vessel (kind "tortuous").
        spacing: centreline point spacing; wall_rings, wall_around: wall point rings.
        clot_cross, clot_cells: hex cells across the clot diameter and along its length.
        clot_length: placed clot length along the centreline.
        clot_start_range: arc length of the clot's back end (bend: offset from the bend start).
        roll_range: degrees; oversize_range: rest radius / local radius; friction_range;
        drive_ratio_range: final drive / estimated friction hold; flow_speed_range: terminal
        speed of a free clot; young_range, poisson_range: clot stiffness.
        squeeze: placed radius / local radius; ramp_time: drive ramp duration.
        penetration_target: contact stiffness aims at this penetration / radius;
        min_contact_pressure: floor of the pressure (times E) that sizes the stiffness;
        penetration_cap: hard cap on penetration / radius (normal velocity clamp).
        elem_bulk: cap of the per-element bulk modulus, in shear moduli (material.py).
        contact_damping: normal damping ratio; min_alpha: lower bound of mass damping.
        safety: fraction of the stable substep; exit_margin: distance past the outlet.
        outlet_flare, outlet_flare_length: the outlet widens by this fraction of its radius
            over this length (cases.build_vessel).
        n_buffer: stored dense frames (odd); max_substeps: safety cap per simulation.
        batch_size: simulations run together with ``vmap`` (same mesh; 1 = one at a time).
    """

    name: str
    kind: str
    n_sims: int
    n_frames: int
    study: str
    radius: float = 1.0
    leg_in: float = 5.0
    leg_out: float = 10.0
    bend_radius: float = 3.0
    bend_angle_deg: float = 90.0
    leg_out_range: tuple[float, float] | None = None
    bend_radius_range: tuple[float, float] | None = None
    bend_angle_range: tuple[float, float] | None = None
    rotation_step_deg: float = 10.0
    rotation_axis: str = "x"
    length: float = 60.0
    min_bend_radius: float = 3.0
    radius_end: float = 1.18
    wobble: float = 0.06
    spacing: float = 0.2
    wall_rings: int = 27
    wall_around: int = 26
    clot_cross: int = 4
    clot_cells: int = 10
    clot_length: float = 3.0
    clot_start_range: tuple[float, float] = (0.5, 1.5)
    roll_range: tuple[float, float] = (0.0, 90.0)
    oversize_range: tuple[float, float] = (1.1, 1.2)
    friction_range: tuple[float, float] = (0.1, 0.3)
    drive_ratio_range: tuple[float, float] = (1.3, 2.0)
    flow_speed_range: tuple[float, float] = (0.15, 0.25)
    young_range: tuple[float, float] = (0.8, 1.2)
    poisson_range: tuple[float, float] = (0.45, 0.49)
    squeeze: float = 0.97
    ramp_time: float = 6.0
    penetration_target: float = 0.005
    min_contact_pressure: float = 0.3
    penetration_cap: float = 0.01
    elem_bulk: float = 4.0
    contact_damping: float = 0.5
    min_alpha: float = 0.5
    safety: float = 0.5
    exit_margin: float = 0.5
    outlet_flare: float = 0.3
    outlet_flare_length: float = 1.5
    n_buffer: int = 161
    max_substeps: int = 200_000
    batch_size: int = 5

    def __post_init__(self) -> None:
        if self.study not in DATASETS:
            raise ConfigError(f"preset {self.name!r}: study must be one of {list(DATASETS)}")
        for field in self.shape_ranges():
            low, high = getattr(self, field)
            if not 0 < low <= high:
                raise ConfigError(f"preset {self.name!r}: {field} must be (low, high) with "
                                  f"0 < low <= high, got {getattr(self, field)}")
        if self.shape_ranges() and (self.kind != "bend" or self.batch_size != 1):
            raise ConfigError(
                f"preset {self.name!r}: {', '.join(self.shape_ranges())} draw a vessel per "
                "simulation: they need kind 'bend' and batch_size 1 (the cases of a batch share "
                f"one vessel), got kind {self.kind!r}, batch_size {self.batch_size}")

    def shape_ranges(self) -> list[str]:
        """The bend's shape fields drawn per simulation (those of its ``*_range`` not None)."""
        names = ("leg_out_range", "bend_radius_range", "bend_angle_range")
        return [n for n in names if getattr(self, n) is not None]

    @property
    def reference_wall_time_s(self) -> float:
        """The study's Abaqus wall time per simulation of this kind of dataset."""
        return DATASETS[self.study].abaqus_s

    @property
    def skip_frames(self) -> int:
        """Frames rollouts skip: the study's share of its simulation (5 of 40 BendVessel frames,
        40 of 200 ClotEntry frames; the solver resamples the whole run to ``n_frames``), at
        least 1: 5 and 40 for the full presets, 1 and 2 for the tiny ones."""
        kind = DATASETS[self.study]
        return max(1, round(kind.skip_frames * self.n_frames / kind.n_frames))

    def to_dict(self) -> dict:
        """JSON-serialisable dictionary of every field."""
        return dataclasses.asdict(self)


PRESETS: dict[str, Preset] = {
    "bendvessel": Preset(
        name="bendvessel", kind="bend", n_sims=20, n_frames=40, study="bendvessel",
        n_buffer=161, safety=0.6, batch_size=20,
    ),
    "bendvessel-tiny": Preset(
        name="bendvessel-tiny", kind="bend", n_sims=4, n_frames=8, study="bendvessel",
        leg_in=2.0, leg_out=3.0, bend_radius=2.5, spacing=0.25, wall_rings=12, wall_around=12,
        clot_cells=6, clot_length=2.0, clot_start_range=(0.3, 0.8), n_buffer=129,
        poisson_range=(0.45, 0.49), max_substeps=40_000,
    ),
    # BendVessel's tube with a new shape per simulation (outlet leg, bend radius and angle
    # drawn around BendVessel's 10 / 3 / 90): for models that must meet vessels they did not see
    "bendvessel-shapes": Preset(
        name="bendvessel-shapes", kind="bend", n_sims=20, n_frames=40, study="bendvessel",
        leg_out_range=(7.0, 13.0), bend_radius_range=(2.5, 4.0), bend_angle_range=(60.0, 120.0),
        n_buffer=161, safety=0.6, batch_size=1,
    ),
    "clotentry": Preset(
        name="clotentry", kind="tortuous", n_sims=10, n_frames=200,
        study="clotentry", length=60.0, spacing=0.25, wall_rings=340,
        wall_around=64, clot_cross=12, clot_cells=30, clot_length=5.0,
        clot_start_range=(1.0, 3.0), ramp_time=12.0, flow_speed_range=(0.4, 0.6),
        oversize_range=(1.08, 1.2),
        safety=0.65, n_buffer=801, batch_size=1, max_substeps=400_000,
    ),
    "clotentry-tiny": Preset(
        name="clotentry-tiny", kind="tortuous", n_sims=4, n_frames=10,
        study="clotentry", length=14.0, spacing=0.25, radius_end=1.0,
        wobble=0.03, wall_rings=30, wall_around=12, clot_cross=4, clot_cells=6,
        clot_length=2.0, clot_start_range=(0.5, 1.5), n_buffer=129, batch_size=1,
        flow_speed_range=(0.12, 0.2), oversize_range=(1.12, 1.2), max_substeps=60_000,
    ),
}  # fmt: skip


def get_preset(name: str) -> Preset:
    """The preset called ``name`` (one of :data:`PRESETS`); unknown names raise ConfigError."""
    try:
        return PRESETS[name.lower()]
    except KeyError:
        raise ConfigError(
            f"unknown solver preset {name!r}; known presets: {', '.join(PRESETS)}"
        ) from None
