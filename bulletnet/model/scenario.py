"""Scenes: TOML files parsed into frozen, validated dataclasses in SI units.

A scene file has one table per section below (or starts from another scene, ``base = "NAME"``,
and gives only what it changes). Every key has a unit (in its docstring and in
``bulletnet params``) and a default; unknown keys, wrong types and out-of-range values are
errors naming the file, the key and what was expected. ``--set section.key=value`` overrides
use the same validation.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..common.errors import ScenarioError
from ..common.resources import data_dir

SCENARIO_DIR = data_dir("scenarios")
"""Folder of the named scenes shipped with the project (``bulletnet run deployment``)."""

ENGINES = ("fast", "bullet", "reference")
EXPONENTIAL = "exponential_euler"
"""Symplectic Euler whose thread dampers relax exactly over each step
(:mod:`bulletnet.solver.exponential_damping`)."""
INTEGRATORS = ("symplectic_euler", "implicit_euler", EXPONENTIAL)
DEFAULT_DT = {"symplectic_euler": 1e-6, "implicit_euler": 1e-5, EXPONENTIAL: 5e-6}
"""Default step of the fixed-step integrators [s] (see README: accuracy against the reference)."""


def _f(default, unit: str, check: str = "", choices: tuple = ()):
    """A dataclass field carrying its SI unit and its validation rule."""
    return field(default=default, metadata={"unit": unit, "check": check, "choices": choices})


SCENE_KINDS = ("net", "cantilever")


@dataclass(frozen=True)
class Scene:
    name: str = _f("unnamed", "-")
    """Short name of the scene [-]."""
    kind: str = _f("net", "-", "choice", SCENE_KINDS)
    """What is built: a square net ([net]) or a clamped two-node beam ([beam], Fig. 2)."""
    description: str = _f("", "-")
    """One-line description [-]."""
    duration: float = _f(3.0, "s", ">0")
    """Simulated time [s]."""
    gravity: tuple = _f((0.0, 0.0, 0.0), "m/s^2", "vec3")
    """Uniform gravitational acceleration [m/s^2], shape (3,)."""


@dataclass(frozen=True)
class Net:
    nodes_per_side: int = _f(11, "-", ">=2")
    """Ns, nodes on a side of the square net [-] (Eq. 1)."""
    mesh_length: float = _f(0.5, "m", ">0")
    """Rest length of an inner thread [m] (l_mesh, Table 1)."""
    corner_thread_length: float = _f(0.70710678, "m", ">0")
    """Rest length of a corner thread [m] (l_CT, Table 1)."""
    corner_mass: float = _f(0.5, "kg", ">0")
    """Mass of each corner mass, without its half corner thread [kg] (m_CM, Table 1)."""
    thread_radius: float = _f(0.001, "m", ">0")
    """Radius of an inner thread [m] (r_net, Table 1)."""
    corner_thread_radius: float = _f(0.002, "m", ">0")
    """Radius of a corner thread [m] (r_CT, Table 1)."""
    fold_ratio: float = _f(0.25, "-", "(0,1]")
    """Initial distance between adjacent nodes over their rest length [-] (Sec. 4: 1/4)."""
    center: tuple = _f((0.0, 0.0, 0.0), "m", "vec3")
    """Initial position of the net's centre [m], shape (3,)."""


@dataclass(frozen=True)
class Beam:
    length: float = _f(0.5, "m", ">0")
    """Beam length L [m]; root clamped at the origin, beam along +x (Fig. 2)."""
    radius: float = _f(0.01, "m", ">0")
    """Radius of the beam's circular section [m]."""
    tip_load: tuple = _f((0.0, 0.0, -262.0), "N", "vec3")
    """Constant force on the tip node [N], shape (3,)."""


@dataclass(frozen=True)
class Bending:
    enabled: bool = _f(False, "-")
    """Oriented nodes with the angular (k_b) and transverse (k_t) springs of Sec. 3.2."""
    stiffness_scale: float = _f(1.0, "-", ">=0")
    """Factor on k_t, k_b and their dampers [-]; 0 is the paper's Table 3 check."""
    every: int = _f(0, "-", ">=0")
    """Evaluate the (soft) bending forces every this many steps, as impulses [-] (multirate);
    0 picks the largest interval resolving the nodes' rotational dynamics (see README)."""


@dataclass(frozen=True)
class Material:
    young_modulus: float = _f(70e9, "Pa", ">0")
    """Young's modulus E [Pa]."""
    density: float = _f(1390.0, "kg/m^3", ">0")
    """Density rho [kg/m^3]."""
    poisson_ratio: float = _f(0.35, "-", "[0,0.5)")
    """Poisson's ratio nu [-]."""


@dataclass(frozen=True)
class Materials:
    net: Material = field(default_factory=Material)
    """Thread material (Technora by default)."""
    corner_mass: Material = field(
        default_factory=lambda: Material(young_modulus=69e9, density=2700.0, poisson_ratio=0.33))
    """Corner-mass material (aluminium by default)."""
    debris: Material = field(
        default_factory=lambda: Material(young_modulus=69e9, density=2700.0, poisson_ratio=0.33))
    """Debris material (aluminium by default)."""


@dataclass(frozen=True)
class Damping:
    axial_ratio: float = _f(0.106, "-", ">=0")
    """Axial damping ratio xi_a [-] (Table 1)."""
    axial_reference_frequency: float = _f(100.544, "rad/s", ">0")
    """omega in c_a = 2 xi_a k_a / omega [rad/s]; 100.544 reproduces Table 7
    (c_a / k_a = 2.1085e-3 s)."""
    bending_ratio: float = _f(0.014, "-", ">=0")
    """Bending damping ratio xi_b [-] (Table 1)."""


@dataclass(frozen=True)
class Launch:
    corner_speed: float = _f(2.5, "m/s", ">=0")
    """Initial speed of each corner mass [m/s] (Sec. 4)."""
    elevation: float = _f(56.5, "deg", "[-90,90]")
    """Angle of the corner-mass velocity above the net plane [deg]; in plane it points
    radially out. The paper gives none; 56.5 is identified from its deployment results
    (Table 4, the 90 % times, the 1.5 s area ratio: docs/launch.md); 45 was the former
    choice."""


CONTACT_SOLVERS = ("sequential", "coupled")


@dataclass(frozen=True)
class Contact:
    enabled: bool = _f(False, "-")
    """Whether the scene has contact at all; a contact-free scene builds no collision shapes."""
    damping_ratio: float = _f(0.01, "-", "[0,1)")
    """Contact damping ratio xi in c_c = 2 xi sqrt(k_c m_c) [-] (Sec. 3.3); below 1
    (underdamped), which the exact contact integrator assumes."""
    model: str = _f("implicit", "-", "choice", ("exact", "implicit"))
    """Normal contact law over a step: ``implicit`` takes a backward-Euler step of Eq. 6, as
    constraint solvers do (Vortex, PyBullet): inelastic at practical steps, and passive;
    ``exact`` follows Eq. 6 through every impact in closed form (the pair's own rebound at
    any step), but beside implicit-Euler threads it can gain energy (see README)."""
    self_contact: bool = _f(True, "-")
    """Whether the net's node spheres also collide with each other (with contact on)."""
    skin: float = _f(0.05, "m", ">0")
    """Margin of the self-contact pair list [m]: pairs closer than their radii plus this
    are tracked; the list is rebuilt when a node has moved 0.4 skin. Also the margin of the
    debris' distance cache: a node's query reaches this much beyond its step, and it is not
    queried again until it may have moved that close (results do not depend on it)."""
    solver: str = _f("sequential", "-", "choice", CONTACT_SOLVERS)
    """How a step's contacts are solved: ``sequential`` solves each one once from its start
    gap with the others held (node-node, then node-debris), removing an overlap the last
    step did not predict by moving the node; ``coupled`` solves them all together by
    projected Gauss-Seidel (to ``tolerance``, warm-started), absorbing such an overlap
    instead (no work done): for stacked contacts, as in a cinched net (docs/capture.md,
    "Contact"; needs ``model = "implicit"``)."""
    tolerance: float = _f(1e-6, "m", ">0")
    """Coupled solver: the sweeps stop when none changes any contact's end-of-step gap by
    more than this [m]. A node placed this far off moves a net thread's tension by its
    stiffness times it (5.5e4 N/m for the capture's 1 m threads: 0.06 N, a ten-thousandth of
    their breaking load); the contacts themselves are far stiffer (k_c ~ 3e9 N/m), so their
    forces are set by the threads they hold (docs/capture.md, "Contact at practical steps")."""
    sweeps: int = _f(500, "-", ">0")
    """Coupled solver: most Gauss-Seidel sweeps in a step [-]; the steps that reach it are
    counted (``stats_contact_unconverged``)."""


@dataclass(frozen=True)
class Friction:
    aluminium_aluminium: float = _f(0.45, "-", ">=0")
    """Static friction coefficient mu_s between aluminium bodies (debris, corner masses) [-]."""
    aluminium_net: float = _f(0.15, "-", ">=0")
    """mu_s between aluminium and the net material (Technora) [-]."""
    net_net: float = _f(0.20, "-", ">=0")
    """mu_s between net nodes (Technora, with nylon's friction) [-]."""
    kinetic_ratio: float = _f(1.25, "-", ">0")
    """mu_s / mu_k [-] (Sec. 5: 1.25 for every pair)."""
    slip: float = _f(1e-6, "s/kg", ">0")
    """Slip coefficient s of the regularized friction (Eq. 12) [s/kg]: below the static
    bound the friction force is -v_t / s."""


@dataclass(frozen=True)
class DebrisScene:
    asset: str = _f("", "-")
    """Debris asset: a name in assets/ (``apollo_csm``, ``envisat``), a path to a .toml of
    parts (frustums, boxes, spheres, meshes at their poses) or to a mesh file (.stl, .obj,
    .glb, .gltf, .ply; coordinates in [m]: give ``mass`` or ``density``); empty: no debris."""
    mass: float = _f(0.0, "kg", ">=0")
    """Mass of a debris given as a mesh file, spread evenly over its volume [kg]; 0: from
    ``density`` (an asset .toml gives its parts' masses)."""
    density: float = _f(0.0, "kg/m^3", ">=0")
    """Density of a debris given as a mesh file [kg/m^3]; 0: from ``mass``."""
    position: tuple = _f((0.0, 0.0, 10.0), "m", "vec3")
    """World position of the debris' body-frame origin (where its asset puts it: the CSM's
    geometric centre, the centre of Envisat's bus) [m], (3,)."""
    rotation: tuple = _f((0.0, 0.0, 0.0), "deg", "vec3")
    """Initial orientation as a rotation vector [deg], (3,): the axis is its direction and
    the angle its length; zero keeps the body axes on the world axes (the CSM's long axis
    along y)."""
    velocity: tuple = _f((0.0, 0.0, 0.0), "m/s", "vec3")
    """Initial velocity of the centre of mass [m/s], (3,)."""
    angular_velocity: tuple = _f((0.0, 0.0, 0.0), "deg/s", "vec3")
    """Initial angular velocity, world frame [deg/s], (3,) (Sec. 5: 5 deg/s about z)."""
    step: float = _f(1.0 / 240.0, "s", ">0")
    """Interval at which the fast engine hands the net's contact impulses to the debris'
    rigid-body dynamics in PyBullet [s] (the debris moves rigidly in between)."""


CLOSING_ROUTES = ("sides", "perimeter")
CLOSING_TRIGGERS = ("time", "contact", "wrap")
TETHER_ATTACHMENTS = ("center", "bridle")


@dataclass(frozen=True)
class Closing:
    enabled: bool = _f(False, "-")
    """Whether the net has a closing mechanism: cables through rings on its perimeter nodes,
    reeled in by winches in the corner masses (docs/capture.md)."""
    route: str = _f("sides", "-", "choice", CLOSING_ROUTES)
    """``sides``: four cables, each from a corner mass along one side of the net to the next
    corner mass, reeled by the winch in its first corner mass; ``perimeter``: one cable from
    corner mass 0 round the whole perimeter back to it, reeled there."""
    length_ratio: float = _f(1.05, "-", ">0")
    """Rest length of each cable over its length along the deployed net (nodes at their
    threads' rest lengths) [-]; above 1 the cable does not hold the deployment back."""
    diameter: float = _f(0.001, "m", ">0")
    """Cable diameter [m]."""
    young_modulus: float = _f(70e9, "Pa", ">0")
    """Cable Young's modulus [Pa] (Technora, as the net)."""
    density: float = _f(1390.0, "kg/m^3", ">0")
    """Cable density [kg/m^3]; its mass is lumped on the ring nodes it starts on (Eq. 2)."""
    damping_ratio: float = _f(0.106, "-", ">=0")
    """Cable damping ratio xi [-] in c = 2 xi k / omega_ref, with the net's reference
    frequency (``damping.axial_reference_frequency``): the threads' law (Eq. 3)."""
    reel_speed: float = _f(0.5, "m/s", ">=0")
    """Speed at which each winch reels its cable in [m/s]."""
    min_length_ratio: float = _f(0.15, "-", "(0,1]")
    """A winch stops when its cable's rest length is down to this share of its initial one
    [-] (the mouth is cinched; its drum is full)."""
    stall_tension: float = _f(5.0, "N", ">0")
    """Cable tension at which a winch stops reeling and holds [N] (it reels on below it)."""
    trigger: str = _f("contact", "-", "choice", CLOSING_TRIGGERS)
    """When the winches start: at ``trigger_time`` (``time``), ``trigger_delay`` after the
    net first touches the debris (``contact``), or at the first recorded frame at which the
    net's wrap (the share of directions from the debris' centre of mass that meet the net)
    reaches ``trigger_wrap`` (``wrap``)."""
    trigger_time: float = _f(0.0, "s", ">=0")
    """Start time of the winches with trigger ``time`` [s]."""
    trigger_delay: float = _f(2.0, "s", ">=0")
    """Delay from the first debris contact to the start of the winches with trigger
    ``contact`` [s]."""
    trigger_wrap: float = _f(0.5, "-", "(0,1]")
    """Wrap at which the winches start with trigger ``wrap`` [-] (a flat net 10 m from the
    debris covers 0.17, a net wrapped all round 1)."""


@dataclass(frozen=True)
class Tether:
    enabled: bool = _f(False, "-")
    """Whether a main tether joins the net to a chaser (docs/capture.md)."""
    attach: str = _f("center", "-", "choice", TETHER_ATTACHMENTS)
    """Where the tether holds the net: its ``center`` node, or the four corner masses
    through a ``bridle`` of four lines meeting at the tether's first node."""
    length: float = _f(50.0, "m", ">0")
    """Rest length of the tether from the net (or the bridle's junction) to the chaser [m]."""
    segments: int = _f(25, "-", ">0")
    """Threads the tether is lumped into [-] (segments - 1 tether nodes between its ends)."""
    bridle_length: float = _f(10.0, "m", ">0")
    """Rest length of each bridle line [m] (attach ``bridle``)."""
    diameter: float = _f(0.002, "m", ">0")
    """Tether (and bridle) diameter [m]."""
    young_modulus: float = _f(70e9, "Pa", ">0")
    """Tether Young's modulus [Pa]."""
    density: float = _f(1390.0, "kg/m^3", ">0")
    """Tether density [kg/m^3]."""
    damping_ratio: float = _f(0.106, "-", ">=0")
    """Tether damping ratio xi [-] in c = 2 xi k / omega_ref (Eq. 3's law)."""
    chaser_mass: float = _f(1000.0, "kg", ">=0")
    """Mass of the chaser, a free body at the tether's far end [kg]; 0 holds the chaser
    fixed (the general pair-list kernels then run the net)."""
    chaser_distance: float = _f(20.0, "m", ">0")
    """Initial distance of the chaser behind the net's centre, along -z [m]; the tether is
    laid straight between them (slack if shorter than its length)."""


TECHNORA_BREAKING_STRESS = 3.4e9
"""Tensile strength of Technora [Pa]: Teijin's datasheet, 24.5 cN/dtex at 1.39 g/cm^3,
347 kgf/mm^2 (docs/strength.md, with the spread)."""


@dataclass(frozen=True)
class Strength:
    """What each element can carry (docs/strength.md). An element's breaking tension [N] is
    its breaking stress times its section, pi d^2 / 4, times its knot efficiency where it is
    knotted. Measured against unless ``breakage`` is on (an element over its strength then
    fails for good)."""

    thread_breaking_stress: float = _f(TECHNORA_BREAKING_STRESS, "Pa", ">0")
    """Breaking stress of the net's threads [Pa] (Technora: Teijin's datasheet)."""
    corner_thread_breaking_stress: float = _f(TECHNORA_BREAKING_STRESS, "Pa", ">0")
    """Breaking stress of the corner threads [Pa] (Technora, as the net's)."""
    knot_efficiency: float = _f(0.25, "-", "(0,1]")
    """Breaking tension of a knotted thread over the straight thread's [-], applied to the
    net's threads and the corner threads (each is tied into net nodes at its ends); not to
    the tether, the bridle or the closing cables (spliced, and run through rings). 0.25 is
    Teijin's knot strength of Technora (loop strength 0.40; rope knots 0.4-0.8)."""
    tether_breaking_stress: float = _f(TECHNORA_BREAKING_STRESS, "Pa", ">0")
    """Breaking stress of the main tether and the bridle's lines [Pa] (Technora)."""
    closing_breaking_stress: float = _f(TECHNORA_BREAKING_STRESS, "Pa", ">0")
    """Breaking stress of the closing cables [Pa] (Technora)."""
    breakage: bool = _f(False, "-")
    """Whether an element whose tension reaches its breaking tension fails for good: from
    that step on it carries no force (its axial and bending springs gone; a closing cable's
    winch stops). Off: strength is only measured against, and no breakage kernel is
    compiled."""


@dataclass(frozen=True)
class Orbit:
    enabled: bool = _f(False, "-")
    """Whether every node, the chaser and the debris feel the Hill-Clohessy-Wiltshire
    accelerations of a circular reference orbit (docs/tow.md); off, the scene is in free
    space (``scene.gravity`` only)."""
    altitude: float = _f(400e3, "m", ">0")
    """Altitude of the circular reference orbit above the Earth's equatorial radius [m]
    (gives the mean motion unless ``mean_motion`` is set)."""
    mean_motion: float = _f(0.0, "rad/s", ">=0")
    """Mean motion n of the reference orbit [rad/s]; 0: from ``altitude``,
    sqrt(mu / (R + altitude)^3)."""
    radial: tuple = _f((1.0, 0.0, 0.0), "-", "vec3")
    """The scene direction of LVLH x, radial (away from the Earth) [-], shape (3,)."""
    along_track: tuple = _f((0.0, 0.0, 1.0), "-", "vec3")
    """The scene direction of LVLH y, along-track (the orbital velocity) [-], shape (3,),
    orthogonal to ``radial``; the default puts the net's approach (+z, chaser to debris) on
    the V-bar, the chaser trailing the debris, so a tow along -z is retrograde."""
    origin: tuple = _f((0.0, 0.0, 0.0), "m", "vec3")
    """The scene point on the reference orbit (the LVLH origin) [m], shape (3,)."""

    @property
    def n(self) -> float:
        """The mean motion in force [rad/s]."""
        from ..kernels.orbit import mean_motion

        return self.mean_motion or mean_motion(self.altitude)


THRUST_PROFILES = ("step", "ramp", "zv", "zvd")
TOW_TRIGGERS = ("time", "captured")
"""When the thrust and the reel start: a time, or a delay after the capture's decision."""


@dataclass(frozen=True)
class Thrust:
    enabled: bool = _f(False, "-")
    """Whether the chaser (the tether's far end) thrusts (docs/tow.md); needs ``[tether]``
    with a free chaser."""
    force: float = _f(100.0, "N", ">0")
    """Thrust at full level [N]."""
    direction: tuple = _f((0.0, 0.0, -1.0), "-", "vec3")
    """Scene direction of the thrust [-], shape (3,), normalized (default: away from the
    net, along the tether)."""
    profile: str = _f("zvd", "-", "choice", THRUST_PROFILES)
    """Rise of the thrust (and its fall at the end of the burn): ``step`` (at once),
    ``ramp`` (linear over ``rise_time``), ``zv`` or ``zvd`` (a step shaped by the
    zero-vibration or zero-vibration-derivative shaper tuned to the tether's axial mode,
    docs/tow.md)."""
    rise_time: float = _f(10.0, "s", ">0")
    """Time over which the ``ramp`` profile rises to full thrust (and falls) [s]."""
    burn_time: float = _f(0.0, "s", ">=0")
    """Length of the burn [s], from the start of its rise (after any pretension) to the
    start of its fall (shaped as its rise); 0: to the end of the run."""
    pretension: float = _f(0.0, "N", ">=0")
    """A low thrust [N] (below ``force``) from the burn's start for ``pretension_time``,
    before the shaped rise to ``force``: it takes up a slack tether gently, so that the
    shaped step starts on a taut one (docs/tow.md); 0: none."""
    pretension_time: float = _f(0.0, "s", ">=0")
    """How long the ``pretension`` thrust acts before the rise to ``force`` [s]."""
    trigger: str = _f("captured", "-", "choice", TOW_TRIGGERS)
    """When the burn starts: at ``trigger_time`` (``time``), or ``trigger_delay`` after the
    frame at which the capture's outcome is decided ``captured`` (``captured``; needs
    ``[outcome]``)."""
    trigger_time: float = _f(0.0, "s", ">=0")
    """Start of the burn with trigger ``time`` [s]."""
    trigger_delay: float = _f(0.0, "s", ">=0")
    """Delay from the capture's decision to the start of the burn with trigger
    ``captured`` [s]."""
    integrator: str = _f("", "-", "choice", ("", *INTEGRATORS))
    """Integrator from the first frame at or after the burn's start ('': the scene's,
    ``simulation.integrator``): a tether snapping taut into a net cinched on the debris needs
    symplectic Euler at a small step, where implicit Euler's large one makes energy
    (docs/tow.md, "The snap blows the run up")."""
    dt: float = _f(0.0, "s", ">=0")
    """Time step from then on [s]; 0: the scene's (``simulation.dt``)."""


@dataclass(frozen=True)
class Reel:
    enabled: bool = _f(False, "-")
    """Whether the chaser reels the main tether in or out during the run, changing its
    deployed length (docs/tow.md); needs ``[tether]`` with a free chaser."""
    speed: float = _f(0.0, "m/s")
    """Speed at which the reel's motor changes the deployed length [m/s]: reel-in positive
    (the tether shortens), pay-out negative; 0: no motor (the brake alone)."""
    tension_limit: float = _f(0.0, "N", ">=0")
    """Tension of the tether at the chaser (its last segment) above which the reel's brake
    slips, paying out just enough to hold it there [N] (docs/tow.md); 0: none (the reel
    holds any tension)."""
    min_length: float = _f(1.0, "m", ">0")
    """Least deployed length of the tether [m]: the motor stops reeling in there."""
    max_length: float = _f(0.0, "m", ">=0")
    """Largest deployed length of the tether [m]: the line on the drum runs out there, and
    neither the motor nor the brake pays out more; 0: no limit."""
    trigger: str = _f("captured", "-", "choice", TOW_TRIGGERS)
    """When the reel starts: at ``trigger_time`` (``time``), or ``trigger_delay`` after the
    frame at which the capture's outcome is decided ``captured`` (``captured``; needs
    ``[outcome]``), as ``[thrust]``'s burn does. Before that the drum is locked."""
    trigger_time: float = _f(0.0, "s", ">=0")
    """Start of the reel with trigger ``time`` [s]."""
    trigger_delay: float = _f(0.0, "s", ">=0")
    """Delay from the capture's decision to the start of the reel with trigger
    ``captured`` [s]."""


@dataclass(frozen=True)
class TowRules:
    enabled: bool = _f(False, "-")
    """Judge the tow while the run goes (from the start of the burn) and record its outcome
    and measures (``tow_*`` attributes; needs ``[thrust]``, debris and contact)."""
    safe_distance: float = _f(10.0, "m", ">0")
    """``collided``: the chaser comes closer than this to the debris' centre of mass [m]
    (the debris overruns it)."""
    enclosed_fraction: float = _f(0.5, "-", "(0,1]")
    """``slipped``: the share of the debris' volume inside the net's convex hull falls
    below this [-] (the debris leaves the net)."""
    lost_distance: float = _f(0.0, "m", ">=0")
    """``slipped`` also: the chaser draws farther than this from the debris' centre of mass
    [m] (the net has torn or let go and the debris no longer follows, while a torn net's
    scattered nodes may still hull it); 0: no such bound."""
    slack_tension: float = _f(0.0, "N", ">=0")
    """The tether counts as slack at or below this tension [N] (a snap is the return from
    slack to taut)."""
    stop_when_decided: bool = _f(False, "-")
    """End the run (status ``completed``) at the frame that decides the tow ``slipped`` or
    ``collided``, or that decides the capture otherwise than ``captured`` with
    ``thrust.trigger = "captured"`` (no burn will start); ``towed`` is decided at the end."""


@dataclass(frozen=True)
class Simulation:
    engine: str = _f("fast", "-", "choice", ENGINES)
    """Engine: fast (compiled kernels), bullet (PyBullet bodies) or reference (scipy solve_ivp)."""
    integrator: str = _f("symplectic_euler", "-", "choice", INTEGRATORS)
    """Time integrator of the fast and bullet engines."""
    dt: float = _f(0.0, "s", ">=0")
    """Time step [s]; 0 picks the engine's and integrator's default."""
    record_rate: float = _f(100.0, "Hz", ">0")
    """Frames recorded per simulated second [Hz]."""
    cg_tolerance: float = _f(1e-4, "-", ">0")
    """Relative residual at which implicit_euler's conjugate-gradient solve stops [-]. On
    the 3 s deployment with bending at 3e-5 s, 1e-4, 1e-6 and 1e-8 give 0.649, 0.656 and
    0.662 mm (3.8, 11.6 and 19.1 iterations a step); without bending 1e-4 costs 15-70 % more
    error than 1e-8 (docs/speed.md). Relative to each step's right-hand side, so its error is
    added once a step: a finer step wants a tighter tolerance (the capture's first 20 s at
    1.25e-4 s: first contact 99 ms early at 1e-4, at 1e-6 the reference; docs/capture.md).
    The capture scenes take 1e-4 with block D-ILU."""
    preconditioner: str = _f("block_jacobi", "-", "choice", ("block_jacobi", "block_dilu"))
    """Preconditioner of implicit_euler's conjugate gradients: ``block_jacobi`` (each node's
    3 x 3 diagonal block inverted) or ``block_dilu`` (block D-ILU over the threads and the
    cables' spans, the cables' rank-one parts added back by Woodbury: fewer, dearer
    iterations, and at the same tolerance less error; the capture scenes' choice, with
    cg_tolerance 1e-4; bulletnet.solver.dilu, docs/speed.md)."""
    kernels: str = _f("grid", "-", "choice", ("grid", "pairs"))
    """Thread kernels of the fast engine: ``grid`` (stencils over the net's rows and columns,
    for an Eq. 1 net; any other model falls back to pairs) or ``pairs`` (one loop over the
    thread list, the general path). Both give the same results (bit for bit, tested)."""
    rtol: float = _f(1e-8, "-", ">0")
    """Relative tolerance of the reference engine [-]."""
    atol: float = _f(1e-10, "-", ">0")
    """Absolute tolerance of the reference engine [m, m/s]."""

    @property
    def step(self) -> float:
        """The fixed step in force [s]: ``dt``, or the integrator's default; 0 for the
        adaptive reference engine."""
        if self.engine == "reference":
            return 0.0
        return self.dt or DEFAULT_DT[self.integrator]


@dataclass(frozen=True)
class OutcomeRules:
    enabled: bool = _f(False, "-")
    """Judge the capture while the run goes and record its ``outcome`` and ``outcome_time_s``
    (needs debris and contact; docs/capture.md, "Capture score and outcome"). Off, a
    recording's outcome is still computed afterwards by ``bulletnet metrics``."""
    enclosed_fraction: float = _f(0.9, "-", "(0,1]")
    """``captured`` needs at least this share of the debris' volume inside the convex hull
    of the net's nodes [-], with the mouth closed (``mouth_opening``), held ``hold_time``."""
    mouth_opening: float = _f(0.25, "-", ">=0")
    """``captured`` needs the mouth at most this open [-]: the largest distance between two
    perimeter nodes over the deployed net's diagonal (0.25: 7.1 m on the 20 m capture net)."""
    hold_time: float = _f(10.0, "s", ">=0")
    """``captured`` needs both conditions on every frame over this long [s]."""
    quiet_time: float = _f(5.0, "s", ">=0")
    """``escaped``: after touching the debris, no contact for this long [s], with the net's
    centre of mass moving away from the debris'."""
    miss_time: float = _f(0.0, "s", ">=0")
    """``missed``: no contact by this time [s]; 0: by the end of the run."""
    stop_when_decided: bool = _f(False, "-")
    """End the run (status ``completed``) at the frame that decides the outcome."""


@dataclass(frozen=True)
class Scenario:
    scene: Scene = field(default_factory=Scene)
    net: Net = field(default_factory=Net)
    beam: Beam = field(default_factory=Beam)
    bending: Bending = field(default_factory=Bending)
    materials: Materials = field(default_factory=Materials)
    damping: Damping = field(default_factory=Damping)
    launch: Launch = field(default_factory=Launch)
    contact: Contact = field(default_factory=Contact)
    friction: Friction = field(default_factory=Friction)
    debris: DebrisScene = field(default_factory=DebrisScene)
    closing: Closing = field(default_factory=Closing)
    tether: Tether = field(default_factory=Tether)
    strength: Strength = field(default_factory=Strength)
    orbit: Orbit = field(default_factory=Orbit)
    thrust: Thrust = field(default_factory=Thrust)
    reel: Reel = field(default_factory=Reel)
    tow: TowRules = field(default_factory=TowRules)
    simulation: Simulation = field(default_factory=Simulation)
    outcome: OutcomeRules = field(default_factory=OutcomeRules)
    source: str = field(default="<defaults>", compare=False)
    """Where the scene came from (file path or name), for error messages."""

    def with_overrides(self, overrides: dict[str, Any]) -> Scenario:
        """Return a copy with dotted-key overrides (``{"net.nodes_per_side": 6}``; a vector's
        component by index from 0: ``{"debris.position[2]": 12.0}``) applied."""
        doc = to_dict(self)
        for key, value in overrides.items():
            _set_dotted(doc, key, value, self.source)
        return from_dict(doc, self.source)


# ---------------------------------------------------------------------------------------------
# validation

def _check_value(value: Any, f: dataclasses.Field, where: str) -> Any:
    """Validate one scalar/vector value against its field's type and rule; return it in SI."""
    check, unit = f.metadata.get("check", ""), f.metadata.get("unit", "-")
    unit_txt = "" if unit == "-" else f" [{unit}]"
    typ = f.type if isinstance(f.type, str) else f.type.__name__
    if typ == "bool":
        if not isinstance(value, bool):
            raise ScenarioError(f"{where}: expected true or false, got {value!r}")
        return value
    if typ == "str":
        if not isinstance(value, str):
            raise ScenarioError(f"{where}: expected a string, got {value!r}")
        choices = f.metadata.get("choices", ())
        if choices and value not in choices:
            raise ScenarioError(f"{where}: expected one of {', '.join(choices)}, got {value!r}")
        return value
    if check == "vec3":
        if (not isinstance(value, (list, tuple)) or len(value) != 3
                or not all(_is_number(v) for v in value)):
            raise ScenarioError(f"{where}: expected a list of 3 numbers{unit_txt}, got {value!r}")
        if not all(math.isfinite(v) for v in value):
            raise ScenarioError(f"{where}: expected finite numbers{unit_txt}, got {value!r}")
        return tuple(float(v) for v in value)
    if typ == "int":
        if not isinstance(value, int) or isinstance(value, bool):
            raise ScenarioError(f"{where}: expected an integer, got {value!r}")
    elif not _is_number(value):
        raise ScenarioError(f"{where}: expected a number{unit_txt}, got {value!r}")
    if not math.isfinite(value):
        raise ScenarioError(f"{where}: expected a finite number{unit_txt}, got {value!r}")
    ok = {
        "": True,
        ">0": value > 0,
        ">=0": value >= 0,
        ">=2": value >= 2,

        "(0,1]": 0 < value <= 1,
        "[0,0.5)": 0 <= value < 0.5,
        "[0,1)": 0 <= value < 1,
        "[-90,90]": -90 <= value <= 90,
    }[check]
    if not ok:
        expect = {">0": "a positive number", ">=0": "a number >= 0", ">=2": "an integer >= 2",
                  "(0,1]": "a number in (0, 1]", "[0,0.5)": "a number in [0, 0.5)",
                  "[0,1)": "a number in [0, 1)",
                  "[-90,90]": "a number in [-90, 90]"}[check]
        raise ScenarioError(f"{where}: expected {expect}{unit_txt}, got {value!r}")
    return int(value) if typ == "int" else float(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _build(cls, doc: Any, path: str, source: str):
    """Build dataclass ``cls`` from the mapping ``doc`` found at dotted ``path`` of ``source``."""
    if not isinstance(doc, dict):
        raise ScenarioError(f"{source}: [{path}] must be a table, got {doc!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "source"}
    unknown = sorted(set(doc) - set(fields))
    if unknown:
        key = f"{path}.{unknown[0]}" if path else unknown[0]
        raise ScenarioError(f"{source}: unknown key '{key}'" + (
            did_you_mean(key) or f" (expected one of: {', '.join(fields)})"))
    kwargs = {}
    for name, f in fields.items():
        if name not in doc:
            continue
        where = f"{source}: {path}.{name}" if path else f"{source}: {name}"
        sub = f.type if not isinstance(f.type, str) else globals().get(f.type)
        if dataclasses.is_dataclass(sub):
            kwargs[name] = _build(sub, doc[name], f"{path}.{name}" if path else name, source)
        else:
            kwargs[name] = _check_value(doc[name], f, where)
    return cls(**kwargs)


def from_dict(doc: dict, source: str = "<dict>") -> Scenario:
    """Validate a scene document (as parsed from TOML) into a :class:`Scenario`."""
    scenario = dataclasses.replace(_build(Scenario, doc, "", source), source=source)
    _check_consistency(scenario)
    return scenario


def _check_consistency(s: Scenario) -> None:
    """Rules that involve more than one key."""
    step = s.simulation.step
    if step > 0 and s.simulation.record_rate * step > 1.0 + 1e-12:
        raise ScenarioError(
            f"{s.source}: simulation.record_rate: {s.simulation.record_rate:g} Hz is above the "
            f"step rate 1/dt = {1 / step:g} Hz; lower the record rate or the step")
    if s.simulation.dt > s.scene.duration:
        raise ScenarioError(
            f"{s.source}: simulation.dt: {s.simulation.dt} s is longer than scene.duration "
            f"{s.scene.duration} s")
    for section in ("closing", "tether"):
        if getattr(s, section).enabled and s.scene.kind != "net":
            raise ScenarioError(f"{s.source}: {section}.enabled: a {s.scene.kind} scene has no "
                                "net to close or tether")
    if (s.closing.enabled and s.closing.trigger in ("contact", "wrap")
            and not (s.debris.asset and s.contact.enabled)):
        raise ScenarioError(f"{s.source}: closing.trigger: {s.closing.trigger!r} needs debris "
                            "(debris.asset) and contact (contact.enabled); use 'time'")
    if s.closing.enabled and s.simulation.engine == "reference":
        raise ScenarioError(f"{s.source}: closing.enabled: the reference engine has no "
                            "winches; use --engine fast or bullet")
    if s.orbit.enabled:
        _check_orbit(s)
    _check_tow(s)
    if s.outcome.enabled and not (s.debris.asset and s.contact.enabled):
        raise ScenarioError(f"{s.source}: outcome.enabled: judging a capture needs debris "
                            "(debris.asset) and contact (contact.enabled)")
    if s.contact.solver == "coupled" and s.contact.model != "implicit":
        raise ScenarioError(f"{s.source}: contact.solver: 'coupled' solves the implicit law; "
                            f"set contact.model = 'implicit' (got {s.contact.model!r})")


def _check_orbit(s: Scenario) -> None:
    """An orbit's axes: nonzero and orthogonal; no orbit on the reference engine."""
    o = s.orbit
    radial, along = (math.hypot(*v) for v in (o.radial, o.along_track))
    if radial == 0 or along == 0:
        raise ScenarioError(f"{s.source}: orbit.{'radial' if radial == 0 else 'along_track'}: "
                            "expected a nonzero direction [-]")
    if abs(sum(a * b for a, b in zip(o.radial, o.along_track, strict=True))) \
            > 1e-9 * radial * along:
        raise ScenarioError(f"{s.source}: orbit.along_track: expected a direction orthogonal "
                            f"to orbit.radial, got {list(o.along_track)}")
    if s.simulation.engine == "reference" and s.debris.asset:
        raise ScenarioError(f"{s.source}: orbit.enabled: the reference engine has no debris "
                            "dynamics to put in orbit; use --engine fast or bullet")


def _check_chaser_part(s: Scenario, section: str) -> None:
    """A part of the chaser (``section`` "thrust" or "reel") needs a free chaser, an engine
    other than the reference, and for trigger ``captured`` the judged capture."""
    rules = getattr(s, section)
    if not rules.enabled:
        return
    if not (s.tether.enabled and s.tether.chaser_mass > 0):
        raise ScenarioError(f"{s.source}: {section}.enabled: a {section} needs a chaser "
                            "(tether.enabled with tether.chaser_mass > 0)")
    if s.simulation.engine == "reference":
        raise ScenarioError(f"{s.source}: {section}.enabled: the reference engine has no "
                            f"{section}; use --engine fast or bullet")
    if rules.trigger == "captured" and (not s.outcome.enabled or s.outcome.stop_when_decided):
        raise ScenarioError(f"{s.source}: {section}.trigger: 'captured' needs outcome.enabled "
                            "without outcome.stop_when_decided; use 'time'")


def _check_reel(s: Scenario) -> None:
    """A reel does something, and the tether's length lies within its limits."""
    r, length = s.reel, s.tether.length
    if r.speed == 0 and r.tension_limit == 0:
        raise ScenarioError(f"{s.source}: reel.speed: a reel without a speed [m/s] or a "
                            "reel.tension_limit [N] does nothing; give one")
    if EXPONENTIAL in (s.simulation.integrator, s.thrust.integrator if s.thrust.enabled else ""):
        raise ScenarioError(f"{s.source}: reel.enabled: the reel sets the tether's damping "
                            f"each step, which {EXPONENTIAL} sets for its step; use "
                            "symplectic_euler or implicit_euler with a reel")
    if r.min_length > length:
        raise ScenarioError(f"{s.source}: reel.min_length: expected at most tether.length "
                            f"({length:g} m), got {r.min_length:g} m")
    if 0 < r.max_length < length:
        raise ScenarioError(f"{s.source}: reel.max_length: expected at least tether.length "
                            f"({length:g} m), or 0 for no limit, got {r.max_length:g} m")


def _check_tow(s: Scenario) -> None:
    """A thrust and a reel need a free chaser (and for trigger ``captured`` the judged
    capture); a judged tow needs a thrust, debris and contact."""
    th = s.thrust
    _check_chaser_part(s, "thrust")
    _check_chaser_part(s, "reel")
    if s.reel.enabled:
        _check_reel(s)
    if th.enabled and math.hypot(*th.direction) == 0:
        raise ScenarioError(f"{s.source}: thrust.direction: expected a nonzero direction [-]")
    if th.enabled and th.pretension >= th.force:
        raise ScenarioError(f"{s.source}: thrust.pretension: expected less than thrust.force "
                            f"({th.force:g} N), got {th.pretension:g} N")
    if s.tow.enabled and not (th.enabled and s.debris.asset and s.contact.enabled):
        raise ScenarioError(f"{s.source}: tow.enabled: judging a tow needs thrust.enabled, "
                            "debris (debris.asset) and contact (contact.enabled)")


def to_dict(s: Any) -> dict:
    """The scene as a plain nested dict (TOML-ready), without its ``source``."""
    out = {}
    for f in dataclasses.fields(s):
        if f.name == "source":
            continue
        v = getattr(s, f.name)
        out[f.name] = to_dict(v) if dataclasses.is_dataclass(v) else (
            list(v) if isinstance(v, tuple) else v)
    return out


def to_toml(s: Scenario) -> str:
    """Serialize a scene to TOML text that :func:`loads` reads back to an equal scene."""
    lines: list[str] = []

    def emit(table: dict, prefix: str) -> None:
        scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
        if scalars:
            lines.append(f"[{prefix}]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in scalars.items())
            lines.append("")
        for k, v in table.items():
            if isinstance(v, dict):
                emit(v, f"{prefix}.{k}" if prefix else k)

    emit(to_dict(s), "")
    return "\n".join(lines)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def _dotted(doc: dict, prefix: str = "") -> list[str]:
    """Every table and key of a nested scene dict, dotted: ``net``, ``net.nodes_per_side``."""
    keys = []
    for name, value in doc.items():
        key = f"{prefix}.{name}" if prefix else name
        keys.append(key)
        if isinstance(value, dict):
            keys.extend(_dotted(value, key))
    return keys


def did_you_mean(key: str) -> str:
    """`` (did you mean 'net.nodes_per_side'?)`` for a misspelt dotted scene key (or table):
    the closest by :func:`difflib.get_close_matches`; "" if none is close."""
    import difflib

    name = split_component(key)[0]
    match = difflib.get_close_matches(
        name, [k for k in _dotted(to_dict(Scenario())) if k != name], n=1)
    return f" (did you mean '{match[0]}'?)" if match else ""


def split_component(key: str) -> tuple[str, int | None]:
    """``"debris.position[2]"`` -> ``("debris.position", 2)``; a plain key -> ``(key, None)``."""
    match = re.fullmatch(r"(.+)\[(\d+)\]", key)
    return (match[1], int(match[2])) if match else (key, None)


def unit_of(key: str) -> str:
    """The SI unit of a dotted scene key (``"-"`` for a dimensionless one); ``name[i]``
    has its vector's unit. An unknown key is a :class:`ScenarioError`."""
    cls: Any = Scenario
    f = None
    for part in split_component(key)[0].split("."):
        fields = {x.name: x for x in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) \
            else {}
        if part not in fields or part == "source":
            raise ScenarioError(f"unknown scene key '{key}'{did_you_mean(key)}")
        f = fields[part]
        cls = f.type if not isinstance(f.type, str) else globals().get(f.type)
    if dataclasses.is_dataclass(cls):
        raise ScenarioError(f"'{key}' is a table, not a scene key")
    return f.metadata.get("unit", "-")


def _set_dotted(doc: dict, key: str, value: Any, source: str) -> None:
    """Set ``key`` (dotted; ``name[i]`` sets component i of a vector) in the nested ``doc``."""
    key_name, component = split_component(key)
    parts = key_name.split(".")
    node = doc
    for i, part in enumerate(parts[:-1]):
        if not isinstance(node.get(part), dict):
            raise ScenarioError(f"{source}: override '{key}': no table "
                                f"'{'.'.join(parts[:i + 1])}'{did_you_mean(key)}")
        node = node[part]
    if parts[-1] not in node or isinstance(node[parts[-1]], dict):
        raise ScenarioError(f"{source}: override '{key}': unknown key{did_you_mean(key)}")
    if component is None:
        node[parts[-1]] = value
        return
    vector = node[parts[-1]]
    if not isinstance(vector, list) or component >= len(vector):
        raise ScenarioError(f"{source}: override '{key}': '{key_name}' has no component "
                            f"{component} (components index a vector from 0)")
    node[parts[-1]] = [value if i == component else v for i, v in enumerate(vector)]


def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``KEY=VALUE`` (VALUE in TOML syntax; bare words are strings) into a pair."""
    if "=" not in text:
        raise ScenarioError(f"--set {text!r}: expected KEY=VALUE, e.g. net.nodes_per_side=6")
    key, raw = (p.strip() for p in text.split("=", 1))
    if not key:
        raise ScenarioError(f"--set {text!r}: empty key")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value


def resolve_path(name_or_path: str) -> Path:
    """A scene given as a path, or by name from the shipped ``scenarios/`` folder."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise ScenarioError(f"{name_or_path}: no such scene file")
        return p
    named = SCENARIO_DIR / f"{name_or_path}.toml"
    plan = _plan_kind(named) if named.is_file() else ""
    if plan:
        what = "an optimisation" if plan == "optimize" else f"a {plan}"
        raise ScenarioError(f"{name_or_path}: {what} file, not a scene; run it with "
                            f"`bulletnet {plan} {named}`")
    if named.is_file():
        return named
    raise ScenarioError(f"{name_or_path}: no such scene (named scenes: "
                        f"{', '.join(scene_names()) or 'none'})")


def _plan_kind(path: Path) -> str:
    """``"optimize"``, ``"study"`` or ``"sweep"`` if a .toml is an optimisation, a study or a
    sweep file (its ``scene`` names the base scene, where a scene's is a table; an
    optimisation has an ``objective``, a study a ``design``), else ``""``."""
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return ""
    if "objective" in doc:
        return "optimize"
    if "design" in doc:
        return "study"
    return "sweep" if isinstance(doc.get("scene"), str) else ""


def scene_names() -> list[str]:
    """Names of the shipped scenes: ``scenarios/*.toml`` without the sweep, study and
    optimisation files."""
    return sorted(q.stem for q in SCENARIO_DIR.glob("*.toml") if not _plan_kind(q))


def _parse(text: str, source: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: malformed TOML: {exc}") from None


def _merge(base: dict, doc: dict) -> dict:
    """``doc``'s keys over ``base``'s, table by table."""
    out = dict(base)
    for key, value in doc.items():
        out[key] = (_merge(base[key], value)
                    if isinstance(value, dict) and isinstance(base.get(key), dict) else value)
    return out


def _with_base(doc: dict, source: str, folder: Path, seen: tuple = ()) -> dict:
    """A scene document with its ``base`` resolved: a scene may start from another one
    (``base = "capture"``, a name or a path relative to its own folder) and give only the
    keys it changes."""
    if "base" not in doc:
        return doc
    name = doc.pop("base")
    if not isinstance(name, str):
        raise ScenarioError(f"{source}: base: expected a scene name or path, got {name!r}")
    relative = folder / name
    path = resolve_path(str(relative) if relative.suffix == ".toml" else name)
    if path.resolve() in seen:
        raise ScenarioError(f"{source}: base: {name} includes itself")
    base = _with_base(_parse(_read(path), str(path)), str(path), path.parent,
                      (*seen, path.resolve()))
    return _merge(base, doc)


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from None


def loads(text: str, source: str = "<string>", folder: Path = Path()) -> Scenario:
    """Parse and validate scene TOML text (a ``base`` path relative to ``folder``)."""
    return from_dict(_with_base(_parse(text, source), source, folder), source)


def load(name_or_path: str, overrides: dict[str, Any] | None = None) -> Scenario:
    """Load a scene by name (``"deployment"``) or path, applying dotted-key overrides."""
    path = resolve_path(name_or_path)
    scenario = loads(_read(path), str(path), path.parent)
    return scenario.with_overrides(overrides) if overrides else scenario
