"""Plant-only physical data per vessel, keyed by vessel name (the shared data is in
:mod:`dpcontrol.models.vessels`; what only the truth model needs lives here).

For every built-in vessel:

* ``wind_type``: the Blendermann (1994) ship type giving the wind force coefficients, and the
  lateral-area centroid ``wind_centroid_frac`` = s_L / L (+ forward of midship);
* ``drift_scale``: multiplier on the thin-wall wave-drift coefficient (1 = Ursell's wall);
* ``loaded``: for the shuttle tanker, the full-load data set; a ``mass_schedule`` factor f moves the
  vessel between ballast (f = 1) and full load (f = m_full/m_ballast ≈ 2.66) by interpolating every
  matrix, the draft and the areas linearly in s = (f − 1)/(m_full/m_ballast − 1) while the rigid-body
  mass is exactly f·m_ballast. Vessels without a loaded variant scale M_RB and M_A by f and the
  draft by f (wall-sided hull), keeping the damping;
* ``default_gnss_noise_m`` / ``default_gyro_noise_deg``: sensor noise when a scenario lists no
  sensors (CyberShip II: seed 000 App. A R = diag(1e-4 m², 1e-4 m², 1e-8 rad²); Blue Lady: seed 004
  R_x = R_y = 0.01 m², R_ψ = 0.1 deg²; mariner: seed 002 compass σ = 0.5°; the others a DP-class
  DGPS σ = 0.3 m and gyro σ = 0.05°);
* ``manoeuvring``: hydrodynamic derivatives for a course-keeping truth model (the mariner).

Mariner derivatives: Chislett & Strøm-Tejsen (1965), Planar Motion Mechanism tests of a Mariner
class vessel, as tabulated in Fossen (2021) and MSS ``mariner.m`` (prime system, L = 160.93 m).
In this table the sway/yaw derivatives Y_r', N_r' already contain the rigid-body Coriolis terms
(the equations are M'ν̇' = [Y', N']), so the linear model M ν̇ + N(u0) ν = b δ has
N(u0) = −[[Y_v, Y_r], [N_v, N_r]] and its first-order Nomoto approximation is |K| = 0.185 1/s,
T = 107.2 s at 7.7175 m/s (seed 002 eq. (57): K = 0.185, T = 107.3; checked in the tests).
Rudder sign: δ > 0 gives a sway force to starboard at the stern, so N_δ < 0 and r/δ has gain −K.
The truth is this linear model (as seed 002's K, T describe it). The cubic cross-flow derivatives of
the same table (Y_vvv, Y_vvr, N_vvv, N_vvr) are deliberately left out: without the surge–sway
couplings of the full model (speed loss in a turn) they alone cut the steady turning rate to 47 %
of K·δ at 5° rudder, a truth no longer described by the seed's K.
"""

from __future__ import annotations

from dataclasses import dataclass

from dpcontrol.models.vessels import SHUTTLE_TANKER_FULL, VesselData


@dataclass(frozen=True)
class ManoeuvringDerivatives:
    """Non-dimensional (prime-system) sway–yaw manoeuvring derivatives.

    Attributes
    ----------
    mass, iz, xg : float
        m', I_z', x_G'.
    y_vdot, y_rdot, n_vdot, n_rdot : float
        Added-mass derivatives.
    y_v, y_r, n_v, n_r : float
        Linear damping derivatives (Coriolis included, see module doc).
    y_d, n_d : float
        Rudder derivatives (δ in rad).
    x_udot : float
        Surge added mass X_u̇' (reported surge mass only; surge is held).
    """

    mass: float
    iz: float
    xg: float
    y_vdot: float
    y_rdot: float
    n_vdot: float
    n_rdot: float
    y_v: float
    y_r: float
    n_v: float
    n_r: float
    y_d: float
    n_d: float
    x_udot: float = 0.0


MARINER_DERIVATIVES = ManoeuvringDerivatives(
    mass=798e-5, iz=39.2e-5, xg=-0.023,
    y_vdot=-748e-5, y_rdot=-9.354e-5, n_vdot=4.646e-5, n_rdot=-43.8e-5,
    y_v=-1160e-5, y_r=-499e-5, n_v=-264e-5, n_r=-166e-5,
    y_d=278e-5, n_d=-139e-5, x_udot=-42e-5,
)


@dataclass(frozen=True)
class PlantVesselExtras:
    """Plant-only data of one vessel (see the module docstring)."""

    wind_type: str = "offshore_supply_vessel"
    wind_centroid_frac: float = 0.0
    drift_scale: float = 1.0
    loaded: VesselData | None = None
    loaded_wind_type: str | None = None
    default_gnss_noise_m: float = 0.3
    default_gyro_noise_deg: float = 0.05
    default_plant_rate_hz: float = 20.0
    manoeuvring: ManoeuvringDerivatives | None = None


EXTRAS: dict[str, PlantVesselExtras] = {
    # Model-scale supply vessel: superstructure forward; lab positioning system (seed 000 R).
    "cybership2": PlantVesselExtras(wind_type="offshore_supply_vessel", wind_centroid_frac=0.15,
                                    default_gnss_noise_m=0.01, default_gyro_noise_deg=0.0057,
                                    default_plant_rate_hz=20.0),
    "supply": PlantVesselExtras(wind_type="offshore_supply_vessel", wind_centroid_frac=0.15,
                                default_plant_rate_hz=20.0),
    # Accommodation aft on a shuttle tanker.
    "shuttle_tanker": PlantVesselExtras(wind_type="tanker_ballast", wind_centroid_frac=-0.1,
                                        loaded=SHUTTLE_TANKER_FULL, loaded_wind_type="tanker_loaded",
                                        default_plant_rate_hz=10.0),
    "shuttle_tanker_full": PlantVesselExtras(wind_type="tanker_loaded", wind_centroid_frac=-0.1,
                                             default_plant_rate_hz=10.0),
    "blue_lady": PlantVesselExtras(wind_type="tanker_loaded", wind_centroid_frac=-0.1,
                                   default_gnss_noise_m=0.1, default_gyro_noise_deg=0.316,
                                   default_plant_rate_hz=20.0),
    "mariner": PlantVesselExtras(wind_type="cargo_vessel_loaded", wind_centroid_frac=-0.05,
                                 default_gnss_noise_m=1.0, default_gyro_noise_deg=0.5,
                                 default_plant_rate_hz=10.0, manoeuvring=MARINER_DERIVATIVES),
}


def extras_for(vessel: VesselData) -> PlantVesselExtras:
    """Plant extras of ``vessel``: by name; an inline ``base: X`` vessel (named ``X_custom`` unless
    renamed) inherits X's; otherwise generic values (supply-vessel wind type, no manoeuvring
    model, sensor noise scaled to the vessel: GNSS σ = min(0.3 m, L/100))."""
    if vessel.name in EXTRAS:
        return EXTRAS[vessel.name]
    if vessel.name.endswith("_custom") and vessel.name[: -len("_custom")] in EXTRAS:
        base = EXTRAS[vessel.name[: -len("_custom")]]
        # an inline vessel's own matrices replace the base's, so never reuse a loaded variant
        return PlantVesselExtras(wind_type=base.wind_type, wind_centroid_frac=base.wind_centroid_frac,
                                 drift_scale=base.drift_scale, default_gnss_noise_m=base.default_gnss_noise_m,
                                 default_gyro_noise_deg=base.default_gyro_noise_deg,
                                 default_plant_rate_hz=base.default_plant_rate_hz)
    return PlantVesselExtras(default_gnss_noise_m=min(0.3, vessel.length_m / 100.0))
