"""Vessel parameter sets (SI), shared by the controller's design models and the plant.

The controller uses the low-frequency design data (``mass_matrix`` = M_RB + M_A at zero
frequency, linear ``damping_matrix`` D, seed 002 eqs. (10)–(12)). The plant (``sim_plant``)
builds its *truth* model from the same vessel plus the physical extras kept here (rigid-body
mass and inertia, centre of gravity, quadratic damping, projected areas), integrated
nonlinearly — so the filter's design model is never the plant.

Every built-in vessel cites its source; where a paper gives no value, the estimate and how it was
made is written beside it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dpbase.schema import ConfigError, Section, parse_list
from dpcontrol.models.thrusters import ThrusterSpec, parse_thruster

RHO_SEA_KGPM3 = 1025.0
RHO_FRESH_KGPM3 = 1000.0
GRAVITY_MPS2 = 9.81


def _frozen(matrix: Any) -> np.ndarray:
    array = np.array(matrix, dtype=float)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class VesselData:
    """A vessel: design matrices, physical extras and thrusters.

    Attributes
    ----------
    name : str
        Identifier (``cybership2``, ``supply``, ...).
    description, source : str
        What it is, and where every number comes from.
    length_m, beam_m, draft_m : float
        Main dimensions [m].
    mass_kg : float
        Rigid-body mass (displacement) [kg].
    mass_matrix : ndarray, shape (3, 3)
        M = M_RB + M_A (surge, sway, yaw) [kg, kg·m, kg·m²] (seed 002 eq. (12)).
    damping_matrix : ndarray, shape (3, 3)
        Linear damping D [N·s/m, N·s, N·m·s] (seed 002 eq. (10)).
    iz_kgm2 : float
        Rigid-body yaw moment of inertia about the control origin [kg·m²].
    xg_m : float
        Longitudinal position of the centre of gravity [m].
    quadratic_damping : ndarray, shape (3,)
        Quadratic damping coefficients [X|u|u, Y|v|v, N|r|r] [N·s²/m², N·s²/m², N·m·s²] (>= 0; plant).
    frontal_wind_area_m2, lateral_wind_area_m2 : float
        Projected wind areas above the waterline [m²] (wind loads, seed 002 eq. (18)).
    thrusters : tuple of ThrusterSpec
        Propulsion layout.
    nomoto_gain_per_s, nomoto_time_constant_s : float or None
        First-order Nomoto heading model r/δ = K/(1+Ts) (seed 002 eq. (57)), where known.
    service_speed_mps : float
        Forward speed for course-keeping vessels (0 for DP vessels) [m/s].
    water_density_kgpm3 : float
        Density of the water the vessel floats in [kg/m³].
    """

    name: str
    description: str
    source: str
    length_m: float
    beam_m: float
    draft_m: float
    mass_kg: float
    mass_matrix: np.ndarray
    damping_matrix: np.ndarray
    iz_kgm2: float
    xg_m: float = 0.0
    quadratic_damping: np.ndarray = field(default_factory=lambda: _frozen([0.0, 0.0, 0.0]))
    frontal_wind_area_m2: float = 0.0
    lateral_wind_area_m2: float = 0.0
    thrusters: tuple[ThrusterSpec, ...] = ()
    nomoto_gain_per_s: float | None = None
    nomoto_time_constant_s: float | None = None
    service_speed_mps: float = 0.0
    water_density_kgpm3: float = RHO_SEA_KGPM3

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass_matrix", _frozen(self.mass_matrix))
        object.__setattr__(self, "damping_matrix", _frozen(self.damping_matrix))
        object.__setattr__(self, "quadratic_damping", _frozen(self.quadratic_damping))
        if self.mass_matrix.shape != (3, 3) or self.damping_matrix.shape != (3, 3):
            raise ValueError(f"vessel {self.name}: mass and damping matrices must be 3x3")
        if np.any(np.linalg.eigvalsh(0.5 * (self.mass_matrix + self.mass_matrix.T)) <= 0.0):
            raise ValueError(f"vessel {self.name}: mass matrix must be positive definite")
        names = [t.name for t in self.thrusters]
        if len(set(names)) != len(names):
            raise ValueError(f"vessel {self.name}: thruster names must be unique")

    @property
    def added_mass_matrix(self) -> np.ndarray:
        """M_A = M − M_RB, with M_RB from ``mass_kg``, ``iz_kgm2`` and ``xg_m`` (seed 002 eq. (4))."""
        return self.mass_matrix - rigid_body_mass_matrix(self.mass_kg, self.iz_kgm2, self.xg_m)


def rigid_body_mass_matrix(mass_kg: float, iz_kgm2: float, xg_m: float) -> np.ndarray:
    """M_RB of seed 002 eq. (4): ``[[m,0,0],[0,m,m·xg],[0,m·xg,Iz]]``."""
    return np.array([[mass_kg, 0.0, 0.0], [0.0, mass_kg, mass_kg * xg_m], [0.0, mass_kg * xg_m, iz_kgm2]])


def _deg(value: float) -> float:
    return math.radians(value)


# --------------------------------------------------------------------------------------------
# CyberShip II — 1:70 supply-vessel model, NTNU Marine Cybernetics Laboratory.
# M, D: seed 000 App. A eq. (A.1). m, Iz, xg, quadratic damping: Skjetne, Smogeli & Fossen
# (2004), "Modeling, identification, and adaptive maneuvering of CyberShip II", MIC 25(1).
# Thrusters: two aft main propellers with rudders and one bow tunnel thruster as in Skjetne et
# al. (2004) and Lindegaard & Fossen (2003); force limits sized for the model-scale scenarios
# (layout and capability documented at the tuple).
CYBERSHIP2 = VesselData(
    name="cybership2",
    description="CyberShip II, 1:70 scale supply vessel model (L = 1.255 m)",
    source="M, D: seed 000 App. A (A.1); m, Iz, xg, |u|u damping: Skjetne et al. (2004)",
    length_m=1.255,
    beam_m=0.29,
    draft_m=0.083,
    mass_kg=23.8,
    mass_matrix=np.array([[25.8, 0.0, 0.0], [0.0, 33.8, 1.0115], [0.0, 1.0115, 2.76]]),
    damping_matrix=np.array([[2.0, 0.0, 0.0], [0.0, 7.0, 0.1], [0.0, 0.1, 0.5]]),
    iz_kgm2=1.76,
    xg_m=0.046,
    quadratic_damping=np.array([1.3274, 36.2823, 0.75]),
    frontal_wind_area_m2=0.02,
    lateral_wind_area_m2=0.06,
    # Layout: two aft main propellers at y = ∓0.055 m with rudders (±35°, lift 1.0/rad: a sway force up
    # to 0.6·T ahead, none astern) and a reversible bow tunnel at x = 0.466 m. Limits are model-scale:
    # 2 N ahead / 1 N astern per propeller, ±1 N tunnel, full thrust in ≈ 0.5 s, rudders 60°/s (model
    # servos). Capability (dpcontrol.allocation.capability: wind, current and wave drift collinear,
    # Froude-scaled 1:70): holds ≥ 12.9 m/s full-scale wind from every direction (26 m/s ahead). Not
    # redundant: with a main propeller lost it cannot balance a beam load.
    thrusters=(
        ThrusterSpec("bow_tunnel", "tunnel", x_m=0.466, y_m=0.0, max_thrust_n=1.0, min_thrust_n=-1.0,
                     thrust_rate_limit_nps=2.0, time_constant_s=0.3, angle_rad=_deg(90.0)),
        ThrusterSpec("main_port", "propeller_rudder", x_m=-0.4575, y_m=-0.055, max_thrust_n=2.0,
                     min_thrust_n=-1.0, thrust_rate_limit_nps=4.0, time_constant_s=0.3,
                     azimuth_rate_limit_radps=_deg(60.0), rudder_max_angle_rad=_deg(35.0),
                     rudder_lift_per_rad=1.0),
        ThrusterSpec("main_starboard", "propeller_rudder", x_m=-0.4575, y_m=0.055, max_thrust_n=2.0,
                     min_thrust_n=-1.0, thrust_rate_limit_nps=4.0, time_constant_s=0.3,
                     azimuth_rate_limit_radps=_deg(60.0), rudder_max_angle_rad=_deg(35.0),
                     rudder_lift_per_rad=1.0),
    ),
)


# --------------------------------------------------------------------------------------------
# Offshore supply vessel, L = 76.2 m — Fossen, Sagatun & Sørensen (1996), "Identification of
# dynamically positioned ships", CEP 4(3); bis-scaled matrices as given in Fossen (2021),
# Handbook of Marine Craft Hydrodynamics and Motion Control, 2nd ed., App. D, and in MSS /
# PythonVehicleSimulator `supply`: M = m·T⁻¹·M''·T⁻¹, D = m·√(g/L)·T⁻¹·D''·T⁻¹, T⁻¹ = diag(1, 1, L),
#   M'' = [[1.1274, 0, 0], [0, 1.8902, −0.0744], [0, −0.0744, 0.1278]],
#   D'' = [[0.0358, 0, 0], [0, 0.1183, −0.0124], [0, −0.0041, 0.0308]], m = 6.0·10⁶ kg.
# Seed 001 uses "a typical 100 m DP supply vessel" in MCSim; this is the public stand-in.
# Thrusters (2 tunnels + 2 azimuths): tunnel positions from the same model; azimuth
# positions and all force limits estimated for a DP2 PSV of this size (2 × 1.0 MW tunnels,
# 2 × 2.2 MW azimuths); capability documented at the tuple.
def _supply() -> VesselData:
    mass = 6.0e6
    length = 76.2
    t_inv = np.diag([1.0, 1.0, length])
    m_bis = np.array([[1.1274, 0.0, 0.0], [0.0, 1.8902, -0.0744], [0.0, -0.0744, 0.1278]])
    d_bis = np.array([[0.0358, 0.0, 0.0], [0.0, 0.1183, -0.0124], [0.0, -0.0041, 0.0308]])
    return VesselData(
        name="supply",
        description="Offshore supply vessel, L = 76.2 m (Fossen et al. 1996)",
        source="Fossen, Sagatun & Sørensen (1996) CEP 4(3); Fossen (2021) App. D (bis system)",
        length_m=length,
        beam_m=18.8,
        draft_m=6.0,
        mass_kg=mass,
        mass_matrix=mass * t_inv @ m_bis @ t_inv,
        damping_matrix=mass * math.sqrt(GRAVITY_MPS2 / length) * t_inv @ d_bis @ t_inv,
        # Iz from the radius of gyration 0.25 L; quadratic damping estimated from C_D ≈ 0.1 (surge,
        # frontal), 0.9 (sway, lateral) on the submerged areas; yaw from the sway term × (L/4)³.
        iz_kgm2=mass * (0.25 * length) ** 2,
        xg_m=0.0,
        quadratic_damping=np.array([0.5 * RHO_SEA_KGPM3 * 0.1 * 18.8 * 6.0,
                           0.5 * RHO_SEA_KGPM3 * 0.9 * length * 6.0,
                           0.5 * RHO_SEA_KGPM3 * 0.9 * 6.0 * (length / 4.0) ** 4]),
        frontal_wind_area_m2=280.0,
        lateral_wind_area_m2=720.0,
        # Layout: two reversible bow tunnels (x = 30 / 22 m, ±150 kN ≈ 1.0 MW each) give sway and yaw
        # forward; two azimuths aft (x = −33 m, y = ∓4.5 m, 350 kN ≈ 2.2 MW each, 12°/s) give surge and
        # sway/yaw aft. About 5–7 s from zero to full thrust. Capability (dpcontrol.allocation.capability,
        # Beaufort-5-type collinear wind/current/waves): ≥ 14.0 m/s from every direction (22 m/s ahead,
        # weakest ≈ 75° off the bow); worst single failure (a bow tunnel) 11.7 m/s — DP2-like redundancy.
        thrusters=(
            ThrusterSpec("bow_tunnel_1", "tunnel", x_m=30.0, y_m=0.0, max_thrust_n=150e3, min_thrust_n=-150e3,
                         thrust_rate_limit_nps=30e3, time_constant_s=2.0, angle_rad=_deg(90.0)),
            ThrusterSpec("bow_tunnel_2", "tunnel", x_m=22.0, y_m=0.0, max_thrust_n=150e3, min_thrust_n=-150e3,
                         thrust_rate_limit_nps=30e3, time_constant_s=2.0, angle_rad=_deg(90.0)),
            ThrusterSpec("azimuth_port", "azimuth", x_m=-33.0, y_m=-4.5, max_thrust_n=350e3, min_thrust_n=0.0,
                         thrust_rate_limit_nps=50e3, time_constant_s=2.0,
                         azimuth_rate_limit_radps=_deg(12.0)),
            ThrusterSpec("azimuth_starboard", "azimuth", x_m=-33.0, y_m=4.5, max_thrust_n=350e3,
                         min_thrust_n=0.0, thrust_rate_limit_nps=50e3, time_constant_s=2.0,
                         azimuth_rate_limit_radps=_deg(12.0)),
        ),
    )


SUPPLY = _supply()


# --------------------------------------------------------------------------------------------
# Shuttle tanker, L = 260 m — seed 003 Table 1: L, B, drafts 6.4 m (ballast) / 16.1 m (full),
# mass 58,783 t (ballast) / 156,310 t (full; ratio 2.66), low-frequency surge added mass
# 1,560 t / 8,510 t. (The extracted table lists the added masses in the column order of the
# masses the other way round; surge added mass grows with draft, so 1,560 t is the ballast value.)
# Not in the paper, estimated here:
#   sway added mass   A22 = ρ·π·T²·L/2 (deep-water strip theory, rectangular section ≈ Lewis C=1);
#   yaw inertia       Iz = m·(0.25 L)²;  yaw added inertia A66 = A22·L²/12 (uniform along the hull);
#   linear damping    from time constants M_ii/D_ii: surge 1000 s ("c ≪ c_M", seed 003), sway 100 s,
#                     yaw 80 s — typical for DP tankers (current force ≈ 0.5 MN at 1 m/s beam on).
# Thrusters (bow tunnel + azimuth + main propeller): DP2 shuttle tanker layout with two bow
# tunnels, a retractable bow azimuth, two stern tunnels and a CPP main propeller with rudder
# (capability documented at the tuple).
def _tanker(name: str, mass: float, draft: float, surge_added: float, description: str) -> VesselData:
    length = 260.0
    beam = 44.5
    sway_added = RHO_SEA_KGPM3 * math.pi * draft**2 * length / 2.0
    iz = mass * (0.25 * length) ** 2
    yaw_added = sway_added * length**2 / 12.0
    mass_matrix = np.diag([mass + surge_added, mass + sway_added, iz + yaw_added])
    damping = np.diag([mass_matrix[0, 0] / 1000.0, mass_matrix[1, 1] / 100.0, mass_matrix[2, 2] / 80.0])
    return VesselData(
        name=name,
        description=description,
        source="seed 003 Table 1 (L, B, T, mass, surge added mass); sway/yaw added mass, Iz, D estimated "
               "(see dpcontrol/models/vessels.py)",
        length_m=length,
        beam_m=beam,
        draft_m=draft,
        mass_kg=mass,
        mass_matrix=mass_matrix,
        damping_matrix=damping,
        iz_kgm2=iz,
        xg_m=0.0,
        quadratic_damping=np.array([0.5 * RHO_SEA_KGPM3 * 0.05 * beam * draft,
                           0.5 * RHO_SEA_KGPM3 * 0.7 * length * draft,
                           0.5 * RHO_SEA_KGPM3 * 0.7 * draft * (length / 4.0) ** 4]),
        frontal_wind_area_m2=1200.0 if draft < 10.0 else 900.0,
        lateral_wind_area_m2=5200.0 if draft < 10.0 else 3200.0,
        # Layout (a typical DP2 shuttle tanker, cf. the Navion class): two bow tunnels (x = 118 / 112 m,
        # ±250 kN ≈ 1.8 MW), a retractable bow azimuth (x = 100 m, 300 kN, 8°/s), two stern tunnels
        # (x = −112 / −104 m, ±200 kN) and the CPP main propeller (1.5 MN ahead, 0.9 MN astern,
        # 100 kN/s) with a rudder (±35°, 3°/s, lift 0.8/rad). The second stern tunnel was added in the
        # allocation review: with one, the stern could not balance a beam-on Beaufort 5 (capability
        # 9.6 m/s ballast, 9.0 m/s full); now ≥ 11.1 m/s (ballast) / 10.5 m/s (full) from every direction
        # (22 m/s ahead); worst single failure (a stern tunnel) 9.6 / 8.9 m/s
        # (dpcontrol.allocation.capability). Shuttle tankers keep the weather near the bow (seed 003:
        # aligned with the FPSO), where they hold about twice the beam-on wind.
        thrusters=(
            ThrusterSpec("bow_tunnel_1", "tunnel", x_m=118.0, y_m=0.0, max_thrust_n=250e3, min_thrust_n=-250e3,
                         thrust_rate_limit_nps=40e3, time_constant_s=3.0, angle_rad=_deg(90.0)),
            ThrusterSpec("bow_tunnel_2", "tunnel", x_m=112.0, y_m=0.0, max_thrust_n=250e3, min_thrust_n=-250e3,
                         thrust_rate_limit_nps=40e3, time_constant_s=3.0, angle_rad=_deg(90.0)),
            ThrusterSpec("bow_azimuth", "azimuth", x_m=100.0, y_m=0.0, max_thrust_n=300e3, min_thrust_n=0.0,
                         thrust_rate_limit_nps=40e3, time_constant_s=3.0, azimuth_rate_limit_radps=_deg(8.0)),
            ThrusterSpec("stern_tunnel", "tunnel", x_m=-112.0, y_m=0.0, max_thrust_n=200e3, min_thrust_n=-200e3,
                         thrust_rate_limit_nps=40e3, time_constant_s=3.0, angle_rad=_deg(90.0)),
            ThrusterSpec("stern_tunnel_2", "tunnel", x_m=-104.0, y_m=0.0, max_thrust_n=200e3, min_thrust_n=-200e3,
                         thrust_rate_limit_nps=40e3, time_constant_s=3.0, angle_rad=_deg(90.0)),
            ThrusterSpec("main_propeller", "propeller_rudder", x_m=-128.0, y_m=0.0, max_thrust_n=1500e3,
                         min_thrust_n=-900e3, thrust_rate_limit_nps=100e3, time_constant_s=5.0,
                         azimuth_rate_limit_radps=_deg(3.0), rudder_max_angle_rad=_deg(35.0),
                         rudder_lift_per_rad=0.8),
        ),
    )


SHUTTLE_TANKER = _tanker("shuttle_tanker", 58_783e3, 6.4, 1_560e3,
                         "Shuttle tanker, L = 260 m, ballast condition (seed 003)")
SHUTTLE_TANKER_FULL = _tanker("shuttle_tanker_full", 156_310e3, 16.1, 8_510e3,
                              "Shuttle tanker, L = 260 m, full load (seed 003)")


# --------------------------------------------------------------------------------------------
# Blue Lady — 1:24 training model of a VLCC, Iława ship handling centre (seed 004, Sect. 5):
# L = 13.75 m, B = 2.38 m, m = 22,934 kg; fresh water (lake Silm). Seed 004 models it kinematically
# (m·ẍ = X, eqs. (53)–(55)); the hydrodynamic data below are estimates: draft 0.87 m (VLCC 21 m / 24),
# A11 = 5 % m, A22 = ρπT²L/2, Iz = m(0.25 L)², A66 = A22·L²/12, damping time constants 20/10/8 s.
# Thrusters after Gierusz (2001): main propeller with rudder, bow and stern tunnel thrusters
# (capability documented at the tuple).
def _blue_lady() -> VesselData:
    mass = 22_934.0
    length = 13.75
    draft = 0.87
    sway_added = RHO_FRESH_KGPM3 * math.pi * draft**2 * length / 2.0
    iz = mass * (0.25 * length) ** 2
    mass_matrix = np.diag([1.05 * mass, mass + sway_added, iz + sway_added * length**2 / 12.0])
    return VesselData(
        name="blue_lady",
        description="Blue Lady, 1:24 VLCC training ship (L = 13.75 m)",
        source="seed 004 Sect. 5 (L, B, m); hydrodynamics estimated (see dpcontrol/models/vessels.py)",
        length_m=length,
        beam_m=2.38,
        draft_m=draft,
        mass_kg=mass,
        mass_matrix=mass_matrix,
        damping_matrix=np.diag([mass_matrix[0, 0] / 20.0, mass_matrix[1, 1] / 10.0, mass_matrix[2, 2] / 8.0]),
        iz_kgm2=iz,
        quadratic_damping=np.array([0.5 * RHO_FRESH_KGPM3 * 0.05 * 2.38 * draft,
                           0.5 * RHO_FRESH_KGPM3 * 0.7 * length * draft,
                           0.5 * RHO_FRESH_KGPM3 * 0.7 * draft * (length / 4.0) ** 4]),
        frontal_wind_area_m2=2.5,
        lateral_wind_area_m2=9.0,
        water_density_kgpm3=RHO_FRESH_KGPM3,
        # Layout: bow tunnel (x = 5.6 m, ±500 N), stern tunnel (x = −5.6 m, ±400 N) and the main
        # propeller with rudder aft (1.2 kN ahead, 0.6 kN astern, ±35°, 10°/s — ≈ 2°/s at full scale by
        # Froude scaling). Capability at the Froude-scaled 1:24 environment: ≥ 20 m/s full-scale wind
        # from every direction (dpcontrol.allocation.capability). Not redundant: without the bow tunnel
        # no beam load can be held.
        thrusters=(
            ThrusterSpec("bow_tunnel", "tunnel", x_m=5.6, y_m=0.0, max_thrust_n=500.0, min_thrust_n=-500.0,
                         thrust_rate_limit_nps=250.0, time_constant_s=1.0, angle_rad=_deg(90.0)),
            ThrusterSpec("stern_tunnel", "tunnel", x_m=-5.6, y_m=0.0, max_thrust_n=400.0, min_thrust_n=-400.0,
                         thrust_rate_limit_nps=200.0, time_constant_s=1.0, angle_rad=_deg(90.0)),
            ThrusterSpec("main_propeller", "propeller_rudder", x_m=-6.6, y_m=0.0, max_thrust_n=1200.0,
                         min_thrust_n=-600.0, thrust_rate_limit_nps=400.0, time_constant_s=1.0,
                         azimuth_rate_limit_radps=_deg(10.0), rudder_max_angle_rad=_deg(35.0),
                         rudder_lift_per_rad=1.0),
        ),
    )


BLUE_LADY = _blue_lady()


# --------------------------------------------------------------------------------------------
# Mariner class cargo ship, L = 160.93 m, service speed 15 kn — seed 002: first-order Nomoto model
# K = 0.185 1/s, T = 107.3 s (eq. (57)), compass noise 0.5°, wave model ζ = 0.1, ω0 = 1.2 rad/s.
# Mass and hydrodynamic derivatives from Chislett & Strøm-Tejsen (1965) as listed in Fossen (2021)
# (non-dimensional, prime system: m' = 798e-5, Iz' = 39.2e-5, xG' = −0.023, X_u̇' = −42e-5,
# Y_v̇' = −748e-5, Y_ṙ' = −9.354e-5, N_v̇' = 4.646e-5, N_ṙ' = −43.8e-5, X_u' = −184e-5,
# Y_v' = −1160e-5, Y_r' = −499e-5, N_v' = −264e-5, N_r' = −166e-5) made dimensional at U = 7.7175 m/s.
def _mariner() -> VesselData:
    length = 160.93
    speed = 7.7175
    half_rho = 0.5 * RHO_SEA_KGPM3
    mass = 798e-5 * half_rho * length**3
    iz = 39.2e-5 * half_rho * length**5
    xg = -0.023 * length
    m_rb = rigid_body_mass_matrix(mass, iz, xg)
    m_a = -np.array([[-42e-5 * half_rho * length**3, 0.0, 0.0],
                     [0.0, -748e-5 * half_rho * length**3, -9.354e-5 * half_rho * length**4],
                     [0.0, 4.646e-5 * half_rho * length**4, -43.8e-5 * half_rho * length**5]])
    m_a = 0.5 * (m_a + m_a.T)  # the design model uses a symmetric M (seed 002 eq. (5))
    damping = -np.array([[-184e-5 * half_rho * length**2 * speed, 0.0, 0.0],
                         [0.0, -1160e-5 * half_rho * length**2 * speed, -499e-5 * half_rho * length**3 * speed],
                         [0.0, -264e-5 * half_rho * length**3 * speed, -166e-5 * half_rho * length**4 * speed]])
    return VesselData(
        name="mariner",
        description="Mariner class cargo ship, L = 160.93 m, 15 kn (seed 002 autopilot case)",
        source="seed 002 (Nomoto K, T); Chislett & Strøm-Tejsen (1965) via Fossen (2021) (M, D)",
        length_m=length,
        beam_m=23.17,
        draft_m=8.23,
        mass_kg=mass,
        mass_matrix=m_rb + m_a,
        damping_matrix=damping,
        iz_kgm2=iz,
        xg_m=xg,
        frontal_wind_area_m2=450.0,
        lateral_wind_area_m2=2400.0,
        nomoto_gain_per_s=0.185,
        nomoto_time_constant_s=107.3,
        service_speed_mps=speed,
        # Layout: one main propeller with rudder (±40°, 5°/s: the limits of Fossen's mariner model). Not
        # a DP vessel — course keeping only, with the rudder commanded directly by the heading autopilot
        # (δ = τ_N/N_δ, seed 002 eq. (67); dpcontrol.control.autopilot).
        thrusters=(
            ThrusterSpec("main_propeller", "propeller_rudder", x_m=-78.0, y_m=0.0, max_thrust_n=1.2e6,
                         min_thrust_n=-6.0e5, thrust_rate_limit_nps=1.0e5, time_constant_s=10.0,
                         azimuth_rate_limit_radps=_deg(5.0), rudder_max_angle_rad=_deg(40.0),
                         rudder_lift_per_rad=1.24),
        ),
    )


MARINER = _mariner()

BUILTIN_VESSELS: Mapping[str, VesselData] = {
    vessel.name: vessel
    for vessel in (CYBERSHIP2, SUPPLY, SHUTTLE_TANKER, SHUTTLE_TANKER_FULL, BLUE_LADY, MARINER)
}


def vessel_from_config(value: object, path: str = "vessel") -> VesselData:
    """Resolve a ``vessel:`` entry of a controller config or scenario file.

    Either the name of a built-in vessel, or an inline mapping with the keys ``name``,
    ``mass_matrix`` (3×3), ``damping_matrix`` (3×3), ``thrusters`` (list) and optionally
    ``length_m, beam_m, draft_m, mass_kg, iz_kgm2, xg_m, quadratic_damping,
    frontal_wind_area_m2, lateral_wind_area_m2, description, source`` — or ``base: <built-in>``
    plus any of those keys to override.

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    if isinstance(value, VesselData):  # already built (e.g. a scenario's vessel handed to the controller)
        return value
    if isinstance(value, str):
        if value not in BUILTIN_VESSELS:
            raise ConfigError(path, "a built-in vessel (" + ", ".join(BUILTIN_VESSELS) + ") or a mapping", value)
        return BUILTIN_VESSELS[value]
    section = Section.of(value, path)
    base: VesselData | None = None
    if section.has("base"):
        base_name = section.string("base", choices=BUILTIN_VESSELS)
        base = BUILTIN_VESSELS[base_name]

    def pick(key: str, reader: Any, *args: Any, **kwargs: Any) -> Any:
        if section.has(key) or base is None:
            return reader(key, *args, **kwargs)
        section.raw(key, None)
        return getattr(base, key)

    mass_matrix = pick("mass_matrix", section.matrix, (3, 3))
    damping_matrix = pick("damping_matrix", section.matrix, (3, 3))
    # Required for a vessel of one's own: every scale-dependent default (the wave filter's process noise, the
    # pole placement, the drift-off horizon, the Froude-scaled fault windows) is derived from it, and a silent
    # default would tune a 60 m vessel as a 1 m model.
    length = pick("length_m", section.number, minimum=0.0, exclusive_minimum=True)
    default_mass = float(mass_matrix[0, 0]) if base is None else base.mass_kg
    if section.has("thrusters") or base is None:
        thrusters = parse_list(section, "thrusters", parse_thruster, required=True, min_items=1)
    else:
        section.raw("thrusters", None)
        thrusters = base.thrusters
    name = section.string("name", None if base is None else f"{base.name}_custom")
    try:
        vessel = VesselData(
            name=name,
            description=section.string("description", base.description if base else "inline vessel"),
            source=section.string("source", base.source if base else "inline configuration"),
            length_m=length,
            beam_m=pick("beam_m", section.number, 0.25 * length, minimum=0.0),
            draft_m=pick("draft_m", section.number, 0.05 * length, minimum=0.0),
            mass_kg=pick("mass_kg", section.number, default_mass, minimum=0.0, exclusive_minimum=True),
            mass_matrix=mass_matrix,
            damping_matrix=damping_matrix,
            iz_kgm2=pick("iz_kgm2", section.number, float(mass_matrix[2, 2]) * 0.9, minimum=0.0,
                         exclusive_minimum=True),
            xg_m=pick("xg_m", section.number, 0.0),
            quadratic_damping=pick("quadratic_damping", section.vector, 3, [0.0, 0.0, 0.0]),
            frontal_wind_area_m2=pick("frontal_wind_area_m2", section.number, 0.0, minimum=0.0),
            lateral_wind_area_m2=pick("lateral_wind_area_m2", section.number, 0.0, minimum=0.0),
            thrusters=thrusters,
            nomoto_gain_per_s=base.nomoto_gain_per_s if base else None,
            nomoto_time_constant_s=base.nomoto_time_constant_s if base else None,
            service_speed_mps=base.service_speed_mps if base else 0.0,
            water_density_kgpm3=base.water_density_kgpm3 if base else RHO_SEA_KGPM3,
        )
    except ValueError as error:
        raise ConfigError(path, "a physically valid vessel", str(error)) from None
    section.finish()
    return vessel
