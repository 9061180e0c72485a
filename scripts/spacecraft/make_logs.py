#!/usr/bin/env python3
"""Spacecraft test logs made with the Basilisk simulator (AVS Lab, package `bsk`).

Each scenario is a rigid spacecraft with reaction wheels (BalancedWheels) that starts from a
tumble (or at rest where the reference it copies does) while the wheel motors follow a known
open-loop torque profile, so that the momentum exchange excites the body. Basilisk integrates
the dynamics; its imuSensor makes the gyro column (white noise, constant bias, bias random walk
bounded by its walk bounds, quantisation by its LSB; with a bias walk the white noise comes from
a small module before it, see RateWhiteNoise); the orbiting scenarios add Earth's point
mass gravity, the GravityGradientEffector, or a centred-dipole magnetic field acting on a
constant residual dipole (MtbEffector) and read by a magnetometer.

For every scenario NAME it (re)writes, in inertia/tests/data/spacecraft/:
    NAME.csv         the log a user's ADCS would have (t, gyro, wheel speeds, and q, r, b when present)
    NAME.toml        the vehicle file (one [[rotor]] table per wheel)
    NAME.truth.toml  the body inertia and the simulation's settings
    NAME.clean.csv   (some scenarios) the same columns with the true body rates

The truth J is what Basilisk's own total angular momentum says: a least-squares fit of
L_B(t) - h(t) = J w(t) over the clean trajectory, with h = sum_i Js_i Omega_i g_i. In Basilisk
2.12 the BalancedWheels model adds only the wheels' spin momentum Js Omega g (and -Js g g^T to
the hub's mass matrix): the hub's inertia is the whole vehicle's with its wheels held still. So
the hub given to Basilisk is the bus with the wheels' masses and inertias (Jt, Js) added as
rigid parts, and that composition is the "J from the configuration" that the fit is compared
with.

Run through scripts/make-spacecraft-logs.sh, which makes the Python environment.
"""

from __future__ import annotations

import importlib.metadata
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np
from Basilisk.architecture import messaging, sysModel
from Basilisk.simulation import (
    GravityGradientEffector,
    MtbEffector,
    imuSensor,
    magneticFieldCenteredDipole,
    magnetometer,
    reactionWheelStateEffector,
    spacecraft,
)
from Basilisk.utilities import (
    RigidBodyKinematics as rbk,
    SimulationBaseClass,
    macros,
    orbitalMotion,
    simIncludeGravBody,
    simIncludeRW,
    simSetPlanetEnvironment,
)

REPO_ROOT = Path(__file__).resolve().parents[2]
OUT_DIR = REPO_ROOT / "inertia" / "tests" / "data" / "spacecraft"

# The gravitational parameter the checks use for the gravity-gradient torque (m^3/s^2).
# Basilisk's Earth (simIncludeGravBody) uses its own value; the two differ by ~1e-8 relative.
MU_EARTH_CHECK_M3_S2 = 3.986004418e14

# Reaction wheels of the CubeSat class (about the size of a 10-20 mN m s wheel).
CUBESAT_WHEEL_JS_KG_M2 = 2.4e-5       # spin-axis inertia
CUBESAT_WHEEL_JT_KG_M2 = 1.5e-5       # transverse inertia (rotor plus its share of housing)
CUBESAT_WHEEL_MASS_KG = 0.13
CUBESAT_WHEEL_MAX_TORQUE_N_M = 2.0e-3
CUBESAT_WHEEL_MAX_SPEED_RPM = 6000.0
# A pyramid's axes lean 35 deg from +z: [sin 35, 0, cos 35] = [0.5736, 0, 0.8192], then turned by
# 90 deg steps about z.
PYRAMID_CANT_FROM_Z_DEG = 35.0
PYRAMID_RADIUS_M = 0.045              # wheel centres on a circle about z, in the plane z = 0

LOG_FLOAT = "%.9g"
LOG_FLOAT_SHORT = "%.7g"              # gyro and wheel speeds


# ---------------------------------------------------------------------------------------------
# Scenario description
# ---------------------------------------------------------------------------------------------

TorqueProfile = Callable[[float], float]


@dataclass
class Wheel:
    axis: np.ndarray                 # unit spin axis in the body (gyro) frame, positive speed
    js_kg_m2: float                  # inertia about the spin axis
    jt_kg_m2: float                  # inertia about any transverse axis through its centre
    mass_kg: float
    position_m: np.ndarray           # wheel centre in the body frame, from the origin B
    speed0_rad_s: float              # initial speed relative to the body
    torque_n_m: TorqueProfile        # commanded motor torque as a function of time (s)
    max_torque_n_m: float
    max_speed_rad_s: float


@dataclass
class Gyro:
    noise_std_rad_s: float                     # white noise per sample
    bias_rad_s: np.ndarray                     # constant bias (and the walk's start)
    walk_step_std_rad_s: float = 0.0           # bias random walk: step per sample
    walk_bound_rad_s: float = 0.0              # bias random walk: imuSensor walk bounds
    lsb_rad_s: float = 0.0                     # quantisation step (0: none)


@dataclass
class Orbit:
    altitude_m: float
    inclination_deg: float
    raan_deg: float
    argument_of_latitude_deg: float


@dataclass
class Scenario:
    name: str
    description: str
    seed: int
    rate_hz: float
    duration_s: float
    integration_step_s: float
    bus_mass_kg: float
    bus_inertia_kg_m2: np.ndarray    # about the bus's own centre of mass
    bus_com_m: np.ndarray            # bus centre of mass in the body frame, from B
    wheels: list[Wheel]
    omega0_rad_s: np.ndarray
    sigma0_bn: np.ndarray            # initial attitude (MRP of B relative to N)
    gyro: Gyro
    orbit: Optional[Orbit] = None
    gravity_gradient: bool = False
    dipole_a_m2: Optional[np.ndarray] = None
    magnetometer_noise_t: float = 0.0
    write_quaternion: bool = False
    write_clean: bool = False


# ---------------------------------------------------------------------------------------------
# Torque profiles (known, open loop, zero mean so wheel speeds stay bounded)
# ---------------------------------------------------------------------------------------------

def sine(amplitude_n_m: float, period_s: float, phase_rad: float = 0.0) -> TorqueProfile:
    return lambda t: amplitude_n_m * math.sin(2.0 * math.pi * t / period_s + phase_rad)


def square(amplitude_n_m: float, period_s: float, delay_s: float = 0.0) -> TorqueProfile:
    """Steps: +amplitude for the first half period, -amplitude for the second."""
    def f(t: float) -> float:
        if t < delay_s:
            return 0.0
        return amplitude_n_m if ((t - delay_s) % period_s) < 0.5 * period_s else -amplitude_n_m
    return f


def triangle(amplitude_n_m: float, period_s: float, delay_s: float = 0.0) -> TorqueProfile:
    """Ramps: from -amplitude up to +amplitude and back down over one period."""
    def f(t: float) -> float:
        if t < delay_s:
            return 0.0
        x = ((t - delay_s) % period_s) / period_s
        return amplitude_n_m * (4.0 * x - 1.0 if x < 0.5 else 3.0 - 4.0 * x)
    return f


def total(*profiles: TorqueProfile) -> TorqueProfile:
    return lambda t: sum(p(t) for p in profiles)


# ---------------------------------------------------------------------------------------------
# Geometry
# ---------------------------------------------------------------------------------------------

def pyramid_axes() -> list[np.ndarray]:
    cant = math.radians(PYRAMID_CANT_FROM_Z_DEG)
    axes = []
    for k in range(4):
        a = math.radians(90.0 * k)
        axes.append(np.array([math.sin(cant) * math.cos(a), math.sin(cant) * math.sin(a), math.cos(cant)]))
    return axes


def pyramid_positions() -> list[np.ndarray]:
    return [PYRAMID_RADIUS_M * np.array([math.cos(math.radians(90.0 * k)), math.sin(math.radians(90.0 * k)), 0.0])
            for k in range(4)]


def symmetric(xx, yy, zz, xy, xz, yz) -> np.ndarray:
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=float)


def shift_inertia(mass_kg: float, offset_m: np.ndarray) -> np.ndarray:
    """Parallel-axis term of a point mass at offset_m from the reference point."""
    r = np.asarray(offset_m, dtype=float)
    return mass_kg * (r @ r * np.eye(3) - np.outer(r, r))


def compose_vehicle(s: Scenario) -> tuple[float, np.ndarray, np.ndarray]:
    """Bus plus wheels held still: total mass, centre of mass (body frame, from B) and inertia
    about that centre of mass. This is the hub Basilisk is given and the configuration truth."""
    mass = s.bus_mass_kg + sum(w.mass_kg for w in s.wheels)
    com = (s.bus_mass_kg * s.bus_com_m + sum(w.mass_kg * w.position_m for w in s.wheels)) / mass
    inertia = s.bus_inertia_kg_m2 + shift_inertia(s.bus_mass_kg, s.bus_com_m - com)
    for w in s.wheels:
        g = w.axis
        inertia = inertia + w.js_kg_m2 * np.outer(g, g) + w.jt_kg_m2 * (np.eye(3) - np.outer(g, g))
        inertia = inertia + shift_inertia(w.mass_kg, w.position_m - com)
    return mass, com, inertia


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Hamilton rotation matrix of a unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def attitude_quaternions(sigma_bn: np.ndarray) -> np.ndarray:
    """Scalar-first quaternions q with v_N = R(q) v_B, from Basilisk's MRPs sigma_BN.

    Basilisk's Euler parameters of sigma_BN (MRP2EP) give, through Schaub's EP2C, the matrix
    [BN] (v_B = [BN] v_N); the same four numbers read as a Hamilton quaternion rotate by [BN]^T,
    i.e. body to inertial. Signs are chosen continuous in time (MRP shadow-set switches flip it).
    """
    q = np.array([rbk.MRP2EP(s) for s in sigma_bn])
    for k in range(1, len(q)):
        if q[k] @ q[k - 1] < 0.0:
            q[k] = -q[k]
    return q


# ---------------------------------------------------------------------------------------------
# Basilisk modules written in Python
# ---------------------------------------------------------------------------------------------

class WheelTorqueProfile(sysModel.SysModel):
    """Writes the wheels' open-loop motor torque commands each integration step."""

    def __init__(self, profiles: list[TorqueProfile]):
        super().__init__()
        self.profiles = profiles
        self.cmdOutMsg = messaging.ArrayMotorTorqueMsg()

    def Reset(self, current_sim_nanos):
        self.UpdateState(current_sim_nanos)

    def UpdateState(self, current_sim_nanos):
        t = current_sim_nanos * 1e-9
        payload = messaging.ArrayMotorTorqueMsgPayload()
        torques = [p(t) for p in self.profiles]
        payload.motorTorque = torques + [0.0] * (messaging.MAX_EFF_CNT - len(torques))
        self.cmdOutMsg.write(payload, current_sim_nanos, self.moduleID)


class RateWhiteNoise(sysModel.SysModel):
    """Adds white noise to the body rate the imuSensor sees.

    The imuSensor has one Gauss-Markov error state per axis: with its propagation matrix A = 0 it
    is white noise, with A = I a random walk held inside its walk bounds; it cannot be both. A
    scenario with a bias random walk therefore keeps the imuSensor for the walk, the constant
    bias and the quantisation, and takes its white noise from this module, placed between the
    spacecraft's state message and the imuSensor, so that the noise is quantised like the rest.
    """

    def __init__(self, noise_std_rad_s: float, seed: int):
        super().__init__()
        self.noise_std_rad_s = noise_std_rad_s
        self.rng = np.random.default_rng(seed)
        self.stateInMsg = messaging.SCStatesMsgReader()
        self.stateOutMsg = messaging.SCStatesMsg()

    def Reset(self, current_sim_nanos):
        pass

    # Everything of the spacecraft's state message that the imuSensor reads.
    COPIED_FIELDS = ("r_BN_N", "v_BN_N", "sigma_BN", "omegaDot_BN_B", "nonConservativeAccelpntB_B",
                     "TotalAccumDV_BN_B", "TotalAccumDVBdy", "MRPSwitchCount")

    def UpdateState(self, current_sim_nanos):
        # The reader returns the spacecraft's own message buffer: copy, never modify it.
        state = self.stateInMsg()
        noisy = messaging.SCStatesMsgPayload()
        for name in self.COPIED_FIELDS:
            setattr(noisy, name, getattr(state, name))
        omega = np.array(state.omega_BN_B) + self.rng.normal(0.0, self.noise_std_rad_s, 3)
        noisy.omega_BN_B = omega.tolist()
        self.stateOutMsg.write(noisy, current_sim_nanos, self.moduleID)


# ---------------------------------------------------------------------------------------------
# Simulation
# ---------------------------------------------------------------------------------------------

def simulate(s: Scenario) -> dict:
    """Runs one scenario in Basilisk and returns its records at the log rate (row 0 is t = 0)."""
    hub_mass, hub_com, hub_inertia = compose_vehicle(s)

    sim = SimulationBaseClass.SimBaseClass()
    process = sim.CreateNewProcess("spacecraft")
    dyn_task, log_task = "dynamics", "sensors"
    log_period_ns = macros.sec2nano(1.0 / s.rate_hz)
    process.addTask(sim.CreateNewTask(dyn_task, macros.sec2nano(s.integration_step_s)), 200)
    process.addTask(sim.CreateNewTask(log_task, log_period_ns), 100)

    sc = spacecraft.Spacecraft()
    sc.ModelTag = s.name
    sc.hub.mHub = hub_mass
    sc.hub.r_BcB_B = hub_com.reshape(3, 1).tolist()
    sc.hub.IHubPntBc_B = hub_inertia.tolist()
    sc.hub.omega_BN_BInit = s.omega0_rad_s.reshape(3, 1).tolist()
    sc.hub.sigma_BNInit = s.sigma0_bn.reshape(3, 1).tolist()

    # Reaction wheels.
    factory = simIncludeRW.rwFactory()
    for w in s.wheels:
        rw = factory.create("custom", w.axis.tolist(), Js=w.js_kg_m2, Omega=w.speed0_rad_s / macros.RPM,
                            Omega_max=w.max_speed_rad_s / macros.RPM, u_max=w.max_torque_n_m,
                            rWB_B=w.position_m.tolist(), RWModel=messaging.BalancedWheels)
        rw.Jt = w.jt_kg_m2
        rw.Jg = w.jt_kg_m2
        rw.mass = w.mass_kg
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    factory.addToSpacecraft("wheels", wheels, sc)
    profile = WheelTorqueProfile([w.torque_n_m for w in s.wheels])
    wheels.rwMotorCmdInMsg.subscribeTo(profile.cmdOutMsg)
    # The spacecraft integrates up to the current time first, then the commands for the next
    # step are computed and latched by the wheels.
    sim.AddModelToTask(dyn_task, sc, 100)
    sim.AddModelToTask(dyn_task, profile, 90)
    sim.AddModelToTask(dyn_task, wheels, 80)

    # Orbit and environment.
    grav_factory = None
    gg = None
    field_model = None
    mtb = None
    if s.orbit is not None:
        grav_factory = simIncludeGravBody.gravBodyFactory()
        earth = grav_factory.createEarth()
        earth.isCentralBody = True
        grav_factory.addBodiesTo(sc)
        elements = orbitalMotion.ClassicElements()
        elements.a = earth.radEquator + s.orbit.altitude_m
        elements.e = 0.0
        elements.i = math.radians(s.orbit.inclination_deg)
        elements.Omega = math.radians(s.orbit.raan_deg)
        elements.omega = 0.0
        elements.f = math.radians(s.orbit.argument_of_latitude_deg)
        r_n, v_n = orbitalMotion.elem2rv(earth.mu, elements)
        sc.hub.r_CN_NInit = np.asarray(r_n).reshape(3, 1).tolist()
        sc.hub.v_CN_NInit = np.asarray(v_n).reshape(3, 1).tolist()
        if s.gravity_gradient:
            gg = GravityGradientEffector.GravityGradientEffector()
            gg.ModelTag = "gravityGradient"
            gg.addPlanetName(earth.planetName)
            sc.addDynamicEffector(gg)
            sim.AddModelToTask(dyn_task, gg, 70)
        if s.dipole_a_m2 is not None or s.magnetometer_noise_t > 0.0:
            # Earth's centred dipole, in a non-rotating Earth frame (no planet state message).
            field_model = magneticFieldCenteredDipole.MagneticFieldCenteredDipole()
            field_model.ModelTag = "magneticField"
            simSetPlanetEnvironment.centeredDipoleMagField(field_model, "earth")
            field_model.addSpacecraftToModel(sc.scStateOutMsg)
            sim.AddModelToTask(dyn_task, field_model, 75)
        if s.dipole_a_m2 is not None:
            mtb_params = messaging.MTBArrayConfigMsgPayload()
            mtb_params.numMTB = 3
            mtb_params.GtMatrix_B = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
            mtb_params.maxMtbDipoles = [10.0, 10.0, 10.0]
            mtb_cmd = messaging.MTBCmdMsgPayload()
            mtb_cmd.mtbDipoleCmds = s.dipole_a_m2.tolist()
            mtb = MtbEffector.MtbEffector()
            mtb.ModelTag = "residualDipole"
            mtb_params_msg = messaging.MTBArrayConfigMsg().write(mtb_params)
            mtb_cmd_msg = messaging.MTBCmdMsg().write(mtb_cmd)
            mtb.mtbParamsInMsg.subscribeTo(mtb_params_msg)
            mtb.mtbCmdInMsg.subscribeTo(mtb_cmd_msg)
            mtb.magInMsg.subscribeTo(field_model.envOutMsgs[0])
            sc.addDynamicEffector(mtb)
            sim.AddModelToTask(dyn_task, mtb, 70)

    # Gyro: imuSensor at the log rate, platform frame = body frame, at the vehicle's CoM.
    imu = imuSensor.ImuSensor()
    imu.ModelTag = "gyro"
    imu.RNGSeed = s.seed
    imu.setBodyToPlatformDCM(0.0, 0.0, 0.0)
    imu.sensorPos_B = hub_com.tolist()
    g = s.gyro
    imu.senRotBias = g.bias_rad_s.tolist()
    front_end = None
    if g.walk_step_std_rad_s > 0.0:
        imu.PMatrixGyro = (g.walk_step_std_rad_s * np.eye(3)).tolist()
        imu.setAMatrixGyro(np.eye(3))
        imu.setWalkBoundsGyro(np.full(3, g.walk_bound_rad_s))
        front_end = RateWhiteNoise(g.noise_std_rad_s, s.seed + 1)
        front_end.ModelTag = "gyroWhiteNoise"
        front_end.stateInMsg.subscribeTo(sc.scStateOutMsg)
        imu.scStateInMsg.subscribeTo(front_end.stateOutMsg)
        sim.AddModelToTask(log_task, front_end, 60)
    else:
        imu.PMatrixGyro = (g.noise_std_rad_s * np.eye(3)).tolist()
        imu.setAMatrixGyro(np.zeros((3, 3)))
        imu.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    if g.lsb_rad_s > 0.0:
        # The imuSensor truncates toward zero: its rounding direction is an enum that Basilisk
        # 2.12 does not wrap for Python, so setRoundDirection cannot be called from here.
        imu.setLSBs(0.0, g.lsb_rad_s)
    sim.AddModelToTask(log_task, imu, 50)

    tam = None
    if s.magnetometer_noise_t > 0.0:
        tam = magnetometer.Magnetometer()
        tam.ModelTag = "magnetometer"
        tam.RNGSeed = s.seed + 2
        tam.setBodyToSensorDCM(0.0, 0.0, 0.0)
        tam.scaleFactor = 1.0
        tam.senNoiseStd = [s.magnetometer_noise_t] * 3
        tam.stateInMsg.subscribeTo(sc.scStateOutMsg)
        tam.magInMsg.subscribeTo(field_model.envOutMsgs[0])
        sim.AddModelToTask(log_task, tam, 50)

    # Recorders at the log rate, after the sensors.
    recorders = {
        "state": sc.scStateOutMsg.recorder(log_period_ns),
        "wheels": wheels.rwSpeedOutMsg.recorder(log_period_ns),
        "gyro": imu.sensorOutMsg.recorder(log_period_ns),
    }
    momentum = sc.logger(["totRotAngMomPntC_N"], log_period_ns)
    recorders["momentum"] = momentum
    if gg is not None:
        recorders["gg"] = gg.gravityGradientOutMsg.recorder(log_period_ns)
    if field_model is not None:
        recorders["field"] = field_model.envOutMsgs[0].recorder(log_period_ns)
    if mtb is not None:
        recorders["mtb"] = mtb.mtbOutMsg.recorder(log_period_ns)
    if tam is not None:
        recorders["tam"] = tam.tamDataOutMsg.recorder(log_period_ns)
    for r in recorders.values():
        sim.AddModelToTask(log_task, r, 10)
    # For the torque checks only: attitude, position, momentum and field at every integration
    # step, so that d/dt of the inertial momentum can be taken by finite differences.
    fine = {}
    if gg is not None or mtb is not None:
        step_ns = macros.sec2nano(s.integration_step_s)
        fine["state"] = sc.scStateOutMsg.recorder(step_ns)
        fine["momentum"] = sc.logger(["totRotAngMomPntC_N"], step_ns)
        if field_model is not None:
            fine["field"] = field_model.envOutMsgs[0].recorder(step_ns)
        for r in fine.values():
            sim.AddModelToTask(dyn_task, r, 1)

    sim.InitializeSimulation()
    # One log period more than the duration: the imuSensor's first output (t = 0) is empty
    # (it has no previous state yet), so the logs start at its second output.
    sim.ConfigureStopTime(macros.sec2nano(s.duration_s + 1.0 / s.rate_hz))
    sim.ExecuteSimulation()

    n = len(s.wheels)
    out = {
        "t_sim": recorders["state"].times() * 1e-9,
        "omega": np.array(recorders["state"].omega_BN_B),
        "sigma": np.array(recorders["state"].sigma_BN),
        "r_n": np.array(recorders["state"].r_CN_N),   # the vehicle's centre of mass
        "wheel_speed": np.array(recorders["wheels"].wheelSpeeds)[:, :n],
        "gyro": np.array(recorders["gyro"].AngVelPlatform),
        "L_n": np.array(momentum.totRotAngMomPntC_N),
    }
    if gg is not None:
        out["gg_torque_b"] = np.array(recorders["gg"].gravityGradientTorque_B)
    if field_model is not None:
        out["field_n"] = np.array(recorders["field"].magField_N)
    if mtb is not None:
        out["mtb_torque_b"] = np.array(recorders["mtb"].mtbNetTorque_B)
    if tam is not None:
        out["tam"] = np.array(recorders["tam"].tam_S)
    if fine:
        out["fine"] = {
            "t_sim": fine["state"].times() * 1e-9,
            "sigma": np.array(fine["state"].sigma_BN),
            "r_n": np.array(fine["state"].r_CN_N),
            "L_n": np.array(fine["momentum"].totRotAngMomPntC_N),
        }
        if "field" in fine:
            out["fine"]["field_n"] = np.array(fine["field"].magField_N)
    for k, v in out.items():
        if isinstance(v, np.ndarray):
            assert len(v) == len(out["t_sim"]), (k, len(v), len(out["t_sim"]))
    return out


# ---------------------------------------------------------------------------------------------
# Truth and checks
# ---------------------------------------------------------------------------------------------

def body_momentum(rec: dict) -> np.ndarray:
    """Basilisk's total rotational angular momentum about C, in body components."""
    return np.array([rbk.MRP2C(s) @ L for s, L in zip(rec["sigma"], rec["L_n"])])


def wheel_momentum(s: Scenario, wheel_speed: np.ndarray) -> np.ndarray:
    """h = sum_i Js_i Omega_i g_i (body frame)."""
    return sum(w.js_kg_m2 * wheel_speed[:, [i]] * w.axis[None, :] for i, w in enumerate(s.wheels))


def fit_inertia(omega: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Least-squares symmetric J with J w = rhs (rows are samples)."""
    rows, values = [], []
    for (x, y, z), b in zip(omega, rhs):
        rows += [[x, 0, 0, y, z, 0], [0, y, 0, x, 0, z], [0, 0, z, 0, x, y]]
        values += list(b)
    p, *_ = np.linalg.lstsq(np.array(rows), np.array(values), rcond=None)
    return symmetric(p[0], p[1], p[2], p[3], p[4], p[5])


def central_difference(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    return (x[2:] - x[:-2]) / (t[2:, None] - t[:-2, None])


def relative_mismatch(a: np.ndarray, b: np.ndarray) -> float:
    """RMS of a - b over the RMS of b."""
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)) / np.mean(np.sum(b ** 2, axis=1))))


def truth_and_checks(s: Scenario, rec: dict, J_config: np.ndarray) -> tuple[np.ndarray, dict]:
    """Fits the truth J and runs the checks on the clean trajectory. Returns J and the numbers."""
    omega = rec["omega"]
    L_b = body_momentum(rec)
    h = wheel_momentum(s, rec["wheel_speed"])
    J = fit_inertia(omega, L_b - h)
    checks = {}
    checks["fit_minus_configuration_max_abs_kg_m2"] = float(np.max(np.abs(J - J_config)))
    residual = L_b - omega @ J.T - h
    checks["momentum_residual_max_N_m_s"] = float(np.max(np.abs(residual)))
    checks["momentum_max_N_m_s"] = float(np.max(np.linalg.norm(L_b, axis=1)))

    # Quaternion convention: R(q) takes body vectors to inertial ones, so R(q)^T L_N = L_B.
    q = attitude_quaternions(rec["sigma"])
    R = np.array([quaternion_to_matrix(qk) for qk in q])
    L_b_from_q = np.einsum("kji,kj->ki", R, rec["L_n"])
    checks["quaternion_body_momentum_max_error_N_m_s"] = float(np.max(np.abs(L_b_from_q - L_b)))
    checks["quaternion_vs_BN_transpose_max_error"] = float(max(
        np.max(np.abs(Rk - rbk.MRP2C(sk).T)) for Rk, sk in zip(R, rec["sigma"])))

    # Inertial momentum: conserved without environment, else its rate is the external torque.
    L_n = rec["L_n"]
    # Scale for the relative numbers: the body's initial momentum J w(0), or the wheels' largest
    # when the vehicle starts at rest (its total momentum is then zero throughout).
    L0 = float(np.linalg.norm(J @ omega[0])) or float(np.max(np.linalg.norm(h, axis=1)))
    checks["momentum_scale_N_m_s"] = L0
    checks["inertial_momentum_change_over_scale"] = float(np.linalg.norm(L_n[-1] - L_n[0]) / L0)
    if "fine" in rec:
        # External torque checks at the integration step: d/dt L_N against the torque model.
        fine = rec["fine"]
        tf = fine["t_sim"]
        R_f = np.array([rbk.MRP2C(sk).T for sk in fine["sigma"]])       # [NB] = R(q)
        dL_n_f = central_difference(tf, fine["L_n"])
        if s.gravity_gradient:
            r_b = np.einsum("kji,kj->ki", R_f, fine["r_n"])
            rn = np.linalg.norm(r_b, axis=1)
            tau_b = 3.0 * MU_EARTH_CHECK_M3_S2 / rn[:, None] ** 5 * np.cross(r_b, r_b @ J.T)
            name = "gg"
        else:
            B_b = np.einsum("kji,kj->ki", R_f, fine["field_n"])
            tau_b = np.cross(s.dipole_a_m2[None, :], B_b)
            name = "dipole"
        tau_n = np.einsum("kij,kj->ki", R_f, tau_b)
        checks[f"{name}_torque_vs_dL_dt_relative_mismatch"] = relative_mismatch(dL_n_f, tau_n[1:-1])
        tau_norm = np.linalg.norm(tau_n, axis=1)
        checks[f"{name}_impulse_abs_integral_over_scale"] = float(
            np.sum(0.5 * (tau_norm[1:] + tau_norm[:-1]) * np.diff(tf)) / L0)
        checks[f"{name}_peak_torque_N_m"] = float(np.max(tau_norm))
        # The same torque model against Basilisk's own torque message at the log rate.
        if s.gravity_gradient:
            r_b = np.einsum("kji,kj->ki", R, rec["r_n"])
            rn = np.linalg.norm(r_b, axis=1)
            tau_log = 3.0 * MU_EARTH_CHECK_M3_S2 / rn[:, None] ** 5 * np.cross(r_b, r_b @ J.T)
            checks["gg_torque_vs_basilisk_message_relative_mismatch"] = relative_mismatch(
                tau_log[1:], rec["gg_torque_b"][1:])
        else:
            B_b = np.einsum("kji,kj->ki", R, rec["field_n"])
            tau_log = np.cross(s.dipole_a_m2[None, :], B_b)
            checks["dipole_torque_vs_basilisk_message_relative_mismatch"] = relative_mismatch(
                tau_log[1:], rec["mtb_torque_b"][1:])
    if "tam" in rec:
        B_b = np.einsum("kji,kj->ki", R, rec["field_n"])
        err = rec["tam"][1:] - B_b[1:]
        checks["magnetometer_error_std_T"] = float(np.std(err))

    # Gyro error as seen in the log rows (from the second sample on).
    err = rec["gyro"][1:] - omega[1:]
    checks["gyro_error_mean_rad_s"] = np.mean(err, axis=0).round(7).tolist()
    detrended = err - np.mean(err, axis=0)
    checks["gyro_error_std_rad_s"] = float(np.std(detrended))
    checks["gyro_error_lag1_autocorrelation"] = float(
        np.mean(detrended[1:] * detrended[:-1]) / np.mean(detrended ** 2))
    if s.gyro.lsb_rad_s > 0.0:
        steps = rec["gyro"][1:] / s.gyro.lsb_rad_s
        checks["gyro_off_lsb_grid_max_lsb"] = float(np.max(np.abs(steps - np.round(steps))))
    checks["wheel_speed_min_rad_s"] = np.min(rec["wheel_speed"], axis=0).round(1).tolist()
    checks["wheel_speed_max_rad_s"] = np.max(rec["wheel_speed"], axis=0).round(1).tolist()
    checks["max_body_rate_rad_s"] = float(np.max(np.linalg.norm(omega, axis=1)))
    return J, checks


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------

def toml_float(x: float, digits: int = 12) -> str:
    """A TOML float (always with a '.' or an exponent, so never read as an integer)."""
    text = f"{x:.{digits}g}"
    if not any(c in text for c in ".en"):
        text += ".0"
    return text


def fmt_axis(x: float) -> str:
    text = f"{x:.9f}".rstrip("0")
    text = text + "0" if text.endswith(".") else text
    return "0.0" if float(text) == 0.0 else text


def fmt_matrix(m: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(toml_float(v) for v in row) + "]" for row in m) + "]"


def fmt_vector(v) -> str:
    return "[" + ", ".join(toml_float(x, 9) for x in v) + "]"


def write_csv(path: Path, s: Scenario, rec: dict, rates: np.ndarray, q: np.ndarray) -> None:
    """One row per log sample from the second simulated one on; t starts at 0."""
    n_wheels = len(s.wheels)
    header = ["t", "wx", "wy", "wz"] + [f"rw{i + 1}_rad_s" for i in range(n_wheels)]
    columns = [(rec["t_sim"] - rec["t_sim"][1])[:, None], rates, rec["wheel_speed"]]
    formats = [LOG_FLOAT] + [LOG_FLOAT_SHORT] * (3 + n_wheels)
    if s.write_quaternion:
        header += ["qw", "qx", "qy", "qz"]
        columns.append(q)
        formats += [LOG_FLOAT] * 4
    if s.orbit is not None:
        header += ["rx", "ry", "rz"]
        columns.append(rec["r_n"])
        formats += [LOG_FLOAT] * 3
    if "tam" in rec:
        header += ["bx", "by", "bz"]
        columns.append(rec["tam"])
        formats += [LOG_FLOAT] * 3
    table = np.hstack(columns)[1:]
    with open(path, "w", newline="\n") as f:
        f.write(",".join(header) + "\n")
        row_format = ",".join(formats) + "\n"
        for row in table:
            f.write(row_format % tuple(row))


def write_vehicle(path: Path, s: Scenario) -> None:
    lines = []
    for i, w in enumerate(s.wheels):
        if lines:
            lines.append("")
        lines += [
            "[[rotor]]",
            f'name = "rw{i + 1}"',
            f'column = "rw{i + 1}_rad_s"',
            f"inertia_kg_m2 = {toml_float(w.js_kg_m2, 9)}",
            "axis = [" + ", ".join(fmt_axis(x) for x in w.axis) + "]",
        ]
    path.write_text("\n".join(lines) + "\n")


def environment_of(s: Scenario) -> list[str]:
    env = []
    if s.gravity_gradient:
        env.append("gravity_gradient")
    if s.dipole_a_m2 is not None:
        env.append("magnetic_dipole")
    return env


def write_truth(path: Path, s: Scenario, J: np.ndarray, J_config: np.ndarray) -> None:
    g = s.gyro
    lines = [
        f"inertia_kg_m2 = {fmt_matrix(J)}",
        f"inertia_from_configuration_kg_m2 = {fmt_matrix(J_config)}",
        f"rate_hz = {toml_float(s.rate_hz)}",
        f"duration_s = {toml_float(s.duration_s)}",
        f"gyro_noise_std_rad_s = {toml_float(g.noise_std_rad_s)}",
        f"gyro_bias_rad_s = {fmt_vector(g.bias_rad_s)}",
        "gyro_bias_walk = { step_std_rad_s_per_sample = %s, bound_rad_s = %s }"
        % (toml_float(g.walk_step_std_rad_s), toml_float(g.walk_bound_rad_s)),
        f"gyro_lsb_rad_s = {toml_float(g.lsb_rad_s, 9)}",
    ]
    if g.lsb_rad_s > 0.0:
        lines.append('gyro_rounding = "toward_zero"')
    lines += [
        "environment = [" + ", ".join(f'"{e}"' for e in environment_of(s)) + "]",
    ]
    if s.dipole_a_m2 is not None:
        lines.append(f"dipole_A_m2 = {fmt_vector(s.dipole_a_m2)}")
    if s.orbit is not None:
        lines.append(f"orbit_altitude_m = {toml_float(s.orbit.altitude_m)}")
    lines += [
        f"seed = {s.seed}",
        f'description = "{s.description}"',
    ]
    path.write_text("\n".join(lines) + "\n")


def make(s: Scenario) -> dict:
    started = time.time()
    rec = simulate(s)
    _, _, J_config = compose_vehicle(s)
    J, checks = truth_and_checks(s, rec, J_config)
    q = attitude_quaternions(rec["sigma"])
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    write_csv(OUT_DIR / f"{s.name}.csv", s, rec, rec["gyro"], q)
    if s.write_clean:
        write_csv(OUT_DIR / f"{s.name}.clean.csv", s, rec, rec["omega"], q)
    write_vehicle(OUT_DIR / f"{s.name}.toml", s)
    write_truth(OUT_DIR / f"{s.name}.truth.toml", s, J, J_config)
    checks["seconds"] = round(time.time() - started, 2)
    print(f"== {s.name}")
    print("   truth J (kg m^2):")
    for row in J:
        print("     " + "  ".join(f"{v:+.9f}" for v in row))
    for k, v in checks.items():
        print(f"   {k}: {v:.3g}" if isinstance(v, float) else f"   {k}: {v}")
    return checks


# ---------------------------------------------------------------------------------------------
# Scenarios
# ---------------------------------------------------------------------------------------------

def cubesat_pyramid_wheels(torques: list[TorqueProfile], speeds0_rad_s: list[float]) -> list[Wheel]:
    return [
        Wheel(axis=a, js_kg_m2=CUBESAT_WHEEL_JS_KG_M2, jt_kg_m2=CUBESAT_WHEEL_JT_KG_M2,
              mass_kg=CUBESAT_WHEEL_MASS_KG, position_m=p, speed0_rad_s=s0, torque_n_m=u,
              max_torque_n_m=CUBESAT_WHEEL_MAX_TORQUE_N_M,
              max_speed_rad_s=CUBESAT_WHEEL_MAX_SPEED_RPM * macros.RPM)
        for a, p, u, s0 in zip(pyramid_axes(), pyramid_positions(), torques, speeds0_rad_s)
    ]


# A 6U-class bus (without its wheels): ~10.5 kg, products of inertia a few percent.
SAT6U_BUS_MASS_KG = 10.5
SAT6U_BUS_INERTIA_KG_M2 = symmetric(0.1650, 0.1420, 0.0560, 0.0042, -0.0031, 0.0025)
SAT6U_BUS_COM_M = np.array([0.004, -0.003, 0.006])


def sat6u_torques(amplitude_n_m: float) -> list[TorqueProfile]:
    """Steps, sinusoids and ramps, a different mix and period on each wheel."""
    a = amplitude_n_m
    return [
        total(sine(a, 97.0), square(0.5 * a, 120.0, delay_s=20.0)),
        total(sine(a, 61.0, 1.0), triangle(0.6 * a, 173.0)),
        total(square(a, 80.0, delay_s=40.0), sine(0.4 * a, 37.0, 2.0)),
        total(triangle(a, 113.0, delay_s=10.0), sine(0.5 * a, 211.0, 0.5)),
    ]


def sat6u_pyramid_10hz() -> Scenario:
    return Scenario(
        name="sat6u-pyramid-10hz",
        description="6U-class bus, four-wheel pyramid, free tumble with open-loop wheel torques, "
                    "no environment, MEMS-like gyro (white noise, constant bias), 10 Hz, 15 min",
        seed=61,
        rate_hz=10.0,
        duration_s=900.0,
        integration_step_s=0.02,
        bus_mass_kg=SAT6U_BUS_MASS_KG,
        bus_inertia_kg_m2=SAT6U_BUS_INERTIA_KG_M2,
        bus_com_m=SAT6U_BUS_COM_M,
        wheels=cubesat_pyramid_wheels(sat6u_torques(1.2e-4), [150.0, -90.0, 60.0, 200.0]),
        omega0_rad_s=np.array([0.09, -0.05, 0.14]),
        sigma0_bn=np.array([0.1, -0.2, 0.3]),
        gyro=Gyro(noise_std_rad_s=3.0e-4, bias_rad_s=np.array([2.0e-4, -1.5e-4, 1.0e-4])),
        write_clean=True,
    )


def mems_walk_10hz() -> Scenario:
    return Scenario(
        name="mems-walk-10hz",
        description="sat6u-pyramid-10hz's vehicle for 5 min with a gyro bias random walk "
                    "(imuSensor, bounded) and 16-bit quantisation at +-500 deg/s (imuSensor LSB, "
                    "truncated toward zero); the white noise is added to the rate before the imuSensor",
        seed=66,
        rate_hz=10.0,
        duration_s=300.0,
        integration_step_s=0.02,
        bus_mass_kg=SAT6U_BUS_MASS_KG,
        bus_inertia_kg_m2=SAT6U_BUS_INERTIA_KG_M2,
        bus_com_m=SAT6U_BUS_COM_M,
        wheels=cubesat_pyramid_wheels(sat6u_torques(1.2e-4), [-120.0, 80.0, 180.0, -40.0]),
        omega0_rad_s=np.array([-0.08, 0.12, 0.09]),
        sigma0_bn=np.array([-0.3, 0.1, 0.05]),
        gyro=Gyro(noise_std_rad_s=2.0e-4, bias_rad_s=np.array([4.0e-4, -3.0e-4, 2.0e-4]),
                  walk_step_std_rad_s=3.0e-6, walk_bound_rad_s=5.0e-4,
                  lsb_rad_s=math.radians(500.0 / 32768.0)),
        write_clean=True,
    )


# The reference's CubeSat class (El Hariry et al. 2025): 24 kg, 0.2 x 0.2 x 0.3 m,
# diag(0.26, 0.26, 0.16) kg m^2, three orthogonal wheels of 1e-4 kg m^2, 0.01 N m, 460 rad/s.
PEER_BUS_MASS_KG = 24.0
PEER_BUS_INERTIA_KG_M2 = np.diag([0.26, 0.26, 0.16])
PEER_WHEEL_JS_KG_M2 = 1.0e-4
PEER_WHEEL_JT_KG_M2 = 6.0e-5
PEER_WHEEL_MASS_KG = 0.25
PEER_WHEEL_OFFSET_M = 0.05
PEER_WHEEL_MAX_TORQUE_N_M = 0.01
PEER_WHEEL_MAX_SPEED_RAD_S = 460.0


def peer_cubesat_1hz() -> Scenario:
    a = 1.0e-3
    torques = [
        total(sine(a, 60.0), square(0.5 * a, 100.0, delay_s=10.0)),
        total(sine(a, 45.0, 1.0), triangle(0.6 * a, 80.0)),
        total(square(a, 70.0, delay_s=5.0), sine(0.5 * a, 33.0, 2.0)),
    ]
    wheels = [
        Wheel(axis=axis, js_kg_m2=PEER_WHEEL_JS_KG_M2, jt_kg_m2=PEER_WHEEL_JT_KG_M2,
              mass_kg=PEER_WHEEL_MASS_KG, position_m=PEER_WHEEL_OFFSET_M * axis, speed0_rad_s=0.0,
              torque_n_m=u, max_torque_n_m=PEER_WHEEL_MAX_TORQUE_N_M,
              max_speed_rad_s=PEER_WHEEL_MAX_SPEED_RAD_S)
        for axis, u in zip(np.eye(3), torques)
    ]
    return Scenario(
        name="peer-cubesat-1hz",
        description="El Hariry et al. (2025) CubeSat class: 24 kg bus diag(0.26, 0.26, 0.16), "
                    "three orthogonal 1e-4 kg m^2 wheels, starts at rest as in the reference, "
                    "wheel-torque excitation, no environment, 0.01 rad/s gyro noise, 1 Hz, 300 s",
        seed=24,
        rate_hz=1.0,
        duration_s=300.0,
        integration_step_s=0.1,
        bus_mass_kg=PEER_BUS_MASS_KG,
        bus_inertia_kg_m2=PEER_BUS_INERTIA_KG_M2,
        bus_com_m=np.zeros(3),
        wheels=wheels,
        omega0_rad_s=np.zeros(3),
        sigma0_bn=np.zeros(3),
        gyro=Gyro(noise_std_rad_s=0.01, bias_rad_s=np.zeros(3)),
        write_clean=True,
    )


# A 16U / microsat-class bus for the orbit scenarios, clearly unequal moments.
LEO_BUS_MASS_KG = 22.0
LEO_BUS_INERTIA_KG_M2 = symmetric(0.420, 0.310, 0.150, 0.012, -0.008, 0.006)
LEO_BUS_COM_M = np.array([0.0, 0.005, -0.004])
LEO_ALTITUDE_M = 500.0e3
LEO_ORBIT = Orbit(altitude_m=LEO_ALTITUDE_M, inclination_deg=51.6, raan_deg=30.0,
                  argument_of_latitude_deg=10.0)
LEO_OMEGA0_RAD_S = np.array([0.012, -0.018, 0.015])
LEO_SIGMA0_BN = np.array([0.2, 0.1, -0.15])
LEO_GYRO = Gyro(noise_std_rad_s=1.0e-4, bias_rad_s=np.array([5.0e-5, -8.0e-5, 3.0e-5]))
LEO_MAGNETOMETER_NOISE_T = 5.0e-8


def leo_period_s() -> float:
    earth = simIncludeGravBody.gravBodyFactory().createEarth()
    a = earth.radEquator + LEO_ALTITUDE_M
    return 2.0 * math.pi * math.sqrt(a ** 3 / earth.mu)


def leo_wheels() -> list[Wheel]:
    """Mild, slow profile: wheel speeds move by ~100 rad/s over minutes."""
    a = 1.0e-5
    torques = [
        sine(a, 600.0),
        total(sine(a, 900.0, 1.0), square(0.3 * a, 1400.0, delay_s=100.0)),
        triangle(a, 750.0, delay_s=50.0),
        total(sine(0.7 * a, 450.0, 2.0), sine(0.4 * a, 1300.0)),
    ]
    return cubesat_pyramid_wheels(torques, [100.0, -150.0, 200.0, -50.0])


def leo_scenario(name: str, description: str, seed: int, periods: float, *, gravity_gradient: bool,
                 dipole: Optional[np.ndarray] = None, write_clean: bool = False) -> Scenario:
    return Scenario(
        name=name,
        description=description,
        seed=seed,
        rate_hz=1.0,
        duration_s=float(math.ceil(periods * leo_period_s())),
        integration_step_s=0.1,
        bus_mass_kg=LEO_BUS_MASS_KG,
        bus_inertia_kg_m2=LEO_BUS_INERTIA_KG_M2,
        bus_com_m=LEO_BUS_COM_M,
        wheels=leo_wheels(),
        omega0_rad_s=LEO_OMEGA0_RAD_S,
        sigma0_bn=LEO_SIGMA0_BN,
        gyro=LEO_GYRO,
        orbit=LEO_ORBIT,
        gravity_gradient=gravity_gradient,
        dipole_a_m2=dipole,
        magnetometer_noise_t=LEO_MAGNETOMETER_NOISE_T if dipole is not None else 0.0,
        write_quaternion=True,
        write_clean=write_clean,
    )


def leo_gg_1hz() -> Scenario:
    return leo_scenario(
        "leo-gg-1hz",
        "500 km circular orbit (51.6 deg), two periods, Earth point-mass gravity with the "
        "GravityGradientEffector, slow tumble, four-wheel pyramid with a mild speed profile, 1 Hz",
        seed=500, periods=2.0, gravity_gradient=True, write_clean=True)


def leo_free_1hz() -> Scenario:
    return leo_scenario(
        "leo-free-1hz",
        "leo-gg-1hz's orbit, vehicle and start for one period without the gravity-gradient "
        "torque (point-mass gravity only), 1 Hz",
        seed=501, periods=1.0, gravity_gradient=False)


LEO_RESIDUAL_DIPOLE_A_M2 = np.array([0.08, -0.05, 0.12])


def leo_dipole_1hz() -> Scenario:
    return leo_scenario(
        "leo-dipole-1hz",
        "leo-gg-1hz's orbit and vehicle for one period with a constant residual dipole "
        "(MtbEffector) in Earth's centred-dipole field (non-rotating Earth), magnetometer "
        "columns, gravity gradient off, 1 Hz",
        seed=502, periods=1.0, gravity_gradient=False, dipole=LEO_RESIDUAL_DIPOLE_A_M2)


SCENARIOS = [sat6u_pyramid_10hz, peer_cubesat_1hz, leo_gg_1hz, leo_free_1hz, leo_dipole_1hz,
             mems_walk_10hz]


def main(argv: list[str]) -> int:
    wanted = set(argv[1:])
    print(f"Basilisk (bsk) {importlib.metadata.version('bsk')}, writing to {OUT_DIR}")
    started = time.time()
    for make_scenario in SCENARIOS:
        s = make_scenario()
        if wanted and s.name not in wanted:
            continue
        make(s)
    print(f"all done in {time.time() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
