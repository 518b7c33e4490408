"""The physical range of every number a user gives: one place for the API, CLI and GUIs.

Each range is a ``Range(label, min, max, unit)`` value, closed at both ends. The API schemas use
``min`` and ``max`` as ``ge``/``le``, the CLI and settings files call ``check``, the GUI sliders
take them as their bounds; every message names the range (``"seed must be within
0-4294967295, got -1"``). The ranges are what the simulated cell and the papers make sense of,
not what the arithmetic survives: a command speed of 1e-6 mm/s is finite but would simulate for
years.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .errors import InvalidInputError


@dataclass(frozen=True)
class Range:
    """A closed range [min, max] of a number given in ``unit``.

    Attributes:
        label: What the number is, for messages ("contact force").
        min: Smallest allowed value, in ``unit``.
        max: Largest allowed value, in ``unit``.
        unit: Unit of the boundary (mm, N, mm/s, s, um), "" for counts and ratios.
        integer: Only whole numbers (seeds, counts).
        default: The value a user who gives none gets, in ``unit`` (the one place its number
            is typed: the settings classes, the CLI and the REST schemas read it here).
    """

    label: str
    min: float
    max: float
    unit: str = ""
    integer: bool = False
    default: float | None = None

    def __contains__(self, value: object) -> bool:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return False
        if isinstance(value, numbers.Integral):  # ints, numpy ints
            return self.min <= int(value) <= self.max  # int against float compares exactly
        number = float(value)  # floats, numpy floats
        if not math.isfinite(number) or (self.integer and not number.is_integer()):
            return False
        return self.min <= number <= self.max

    def default_value(self) -> float:
        """``default`` of a range that has one (the settings classes' defaults read it)."""
        if self.default is None:
            raise ValueError(f"the {self.label} range has no default")
        return self.default

    def text(self) -> str:
        """The range as people write it: ``"1-50 N"``, ``"0-4294967295"``, ``"-360 to 360
        deg"``."""
        unit = f" {self.unit}" if self.unit else ""
        if self.integer:
            low, high = str(int(self.min)), str(int(self.max))
        else:
            low, high = f"{self.min:g}", f"{self.max:g}"
        return f"{low} to {high}{unit}" if self.min < 0 else f"{low}-{high}{unit}"

    def check(
        self,
        value: object,
        name: str | None = None,
        *,
        error: type[InvalidInputError] = InvalidInputError,
    ) -> float | int:
        """``value`` when it is inside the range (an int for integer ranges), else ``error``
        naming ``name`` (default the label) and the range."""
        if value not in self:
            kind = "an integer" if self.integer else "a number"
            shown = f"{value:g}" if isinstance(value, float) else repr(value)
            raise error(f"{name or self.label} must be {kind} within {self.text()}, got {shown}")
        assert isinstance(value, numbers.Real)  # ``in self`` admits real numbers only
        if not self.integer:
            return float(value)
        # An integral float (``in self`` checked it) converts exactly through float.
        return int(value) if isinstance(value, numbers.Integral) else int(float(value))


# --- every run ----------------------------------------------------------------------------
SEED = Range("seed", 0, 2**32 - 1, integer=True)
PORT = Range("port", 1, 65535, integer=True)

# --- lead-through and path learning (chapter sec. 3: 10-20 N contact, a few mm/s) ---------
LEARNING_FORCE_N = Range("contact force", 1.0, 50.0, "N", default=10.0)
LEARNING_SPEED_MM_S = Range("learning speed", 0.5, 50.0, "mm/s", default=5.0)
# The cutter's height above a floor the run meets (a little above: the machining height).
FLOOR_CLEARANCE_MM = Range("floor clearance", 0.0, 5.0, "mm", default=0.5)
PUSH_FORCE_N = Range("push force", 0.0, 200.0, "N", default=10.0)  # the force vector's size
PUSH_TORQUE_NM = Range("push torque", 0.0, 20.0, "N*m")  # a hand's twist on a tool handle
PUSH_DURATION_S = Range("push duration", 0.0, 10.0, "s")
# Force-control jogging (the admittance's speed limit is 50 mm/s) and the guarded touch-off.
JOG_STEP_MM = Range("jog step", 0.0, 200.0, "mm", default=5.0)
JOG_TURN_DEG = Range("jog turn", 0.0, 45.0, "deg", default=2.0)
JOG_SPEED_MM_S = Range("jog speed", 0.5, 50.0, "mm/s", default=10.0)
JOG_RATE_DEG_S = Range("jog rate", 0.5, 30.0, "deg/s", default=10.0)
# A touch stops at the chapter's lightest contact force.
TOUCH_OFF_FORCE_N = Range("touch-off force", 2.0, 50.0, "N", default=10.0)
TOUCH_OFF_TRAVEL_MM = Range("touch-off travel", 0.0, 200.0, "mm", default=30.0)  # and > 0
# The viser push handle: its offset from the TCP times this spring pushes the tool.
HANDLE_SPRING_N_MM = Range("handle spring", 0.1, 5.0, "N/mm")
# Guide points of one project, and samples of one recording (4 ms each: 1 M is 67 min of
# learning, ~260 MB of arrays; the papers' runs are minutes).
GUIDE_POINTS_MAX = 200
RECORDING_SAMPLES_MAX = 1_000_000
# A mesh file a user gives (an upload, ``--workpiece F``, a project's part): bytes, triangles.
MAX_MESH_BYTES = 50 * 1024 * 1024
MAX_MESH_TRIANGLES = 500_000
# Points of a force trace sent for a plot (decimated by stride).
TRACE_POINTS = Range("trace points", 2, 100_000, integer=True)

# --- post-processing (chapter fig. 3: 0.2 mm gave ~300 targets) -----------------------------
TOLERANCE_MM = Range("deviation-height tolerance", 0.01, 5.0, "mm", default=0.2)
# The force filter's band (1.5 x the strongest learning force is 75 N; the F/T sensors of the
# papers measure a few hundred N), the program's feeds by curvature (the chapter's deburring
# feeds are a few mm/s; CMRR_COMMAND_SPEED_MM_S allows 500) and the interaction stiffness that
# moves samples back to the unloaded surface (the papers measured 85-143 N/mm; 0 turns it off).
FORCE_THRESHOLD_N = Range("force threshold", 0.0, 1000.0, "N")
PROGRAM_SPEED_MM_S = Range("program speed", 0.1, 500.0, "mm/s")
CURVATURE_REFERENCE_1_M = Range("reference curvature", 1.0, 1.0e5, "1/m")
CONTACT_STIFFNESS_N_MM = Range("contact stiffness", 0.0, 1.0e5, "N/mm")

# --- CMRR (papers: Fr 20-250 N, spindle limit 300 N, Vr 6-100 mm/s, delta 0.05-0.1) --------
CMRR_REFERENCE_FORCE_N = Range("reference force", 1.0, 1000.0, "N")
CMRR_COMMAND_SPEED_MM_S = Range("command speed", 1.0, 500.0, "mm/s")
CMRR_MIN_SPEED_RATIO = Range("minimum speed ratio", 0.01, 0.99)
# Simulated control samples of one study, all controllers together. The simulation allocates
# ~105 bytes per sample up front (8 records, noise, estimates), so the cap keeps a study near
# 300 MB; the papers' cuts need 23k-63k per controller, and one controller at the slowest
# allowed command speed on any built-in cut (1 mm/s, 2.5 M) still fits.
CMRR_MAX_STUDY_SAMPLES = 3_000_000

# --- compensation (chapter sec. 5: CMM noise 10-50 um, ~30 poses) -------------------------
CMM_NOISE_UM = Range("CMM noise", 0.0, 200.0, "um")
IDENTIFICATION_POSES = Range("identification poses", 3, 500, integer=True)
ILC_ITERATIONS = Range("ILC iterations", 0, 50, integer=True)
FORCE_FILTER_CUTOFF_HZ = Range("force filter cut-off", 0.1, 125.0, "Hz")
# Settings files of the compensation (UR and IRB joints: 1e4-1e6 N*m/rad).
JOINT_STIFFNESS_NM_RAD = Range("joint stiffness", 1.0e2, 1.0e9, "N*m/rad")
TOOL_MASS_KG = Range("tool mass", 0.0, 50.0, "kg")
TOOL_COM_MM = Range("tool centre of mass coordinate", -1000.0, 1000.0, "mm")
SENSOR_FORCE_BIAS_N = Range("force sensor bias", -1000.0, 1000.0, "N")
SENSOR_TORQUE_BIAS_NM = Range("torque sensor bias", -100.0, 100.0, "N*m")
JOINT_STIFFNESS_STD_NM_RAD = Range("joint stiffness uncertainty", 0.0, 1.0e9, "N*m/rad")
# Work-object frame of the demo (robot base frame): the largest arms reach ~3 m.
WOBJ_POSITION_MM = Range("work-object position", -3000.0, 3000.0, "mm")
WOBJ_ROTATION_DEG = Range("work-object rotation", -360.0, 360.0, "deg")

# Ball cutter radius: the design's 1-5 mm cutters, down to 0.5 mm.
TOOL_RADIUS_MM = Range("tool radius", 0.5, 5.0, "mm", default=1.0)

# --- machining run (chapter eq. 6: F = 23 d^0.9 f^0.5; the spindle limit ~150-300 N) ----------
MACHINING_PROCESS_GAIN_N = Range("process gain K", 0.1, 1.0e4, "N")
MACHINING_DEPTH_EXPONENT = Range("depth exponent alpha", 0.0, 3.0)
MACHINING_FEED_EXPONENT = Range("feed exponent beta", 0.01, 2.0)
# Fr defaults to 0.7 of the limit and must stay within CMRR_REFERENCE_FORCE_N (1-1000 N), so
# the limit's range is that range over 0.7, rounded inwards: every limit here is accepted
# everywhere (machining.settings.DEFAULT_REFERENCE_FRACTION; a test checks both ends).
MACHINING_FORCE_LIMIT_N = Range("force limit", 1.5, 1400.0, "N")
# The run's engine settings (MachiningSettings), set by programs rather than people: the spindle
# lag of eq. (3), the planner's acceleration, the force's feed share, the cut's height, the
# sensor's noise, the spacing of the stations where the wall is evaluated and of the offline
# targets. Its filters' cut-offs take FORCE_FILTER_CUTOFF_HZ, its CMM noise CMM_NOISE_UM.
MACHINING_TIME_CONSTANT_S = Range("process time constant tau_m", 0.0, 1.0, "s")
MACHINING_PATH_ACCELERATION_M_S2 = Range("path acceleration", 0.001, 10.0, "m/s^2")
MACHINING_FEED_FORCE_RATIO = Range("feed to normal force ratio", 0.0, 2.0)
MACHINING_AXIAL_ENGAGEMENT_MM = Range("axial engagement", 0.1, 50.0, "mm")
MACHINING_SENSOR_NOISE_N = Range("force sensor noise", 0.0, 50.0, "N")
MACHINING_STATION_SPACING_MM = Range("station spacing", 0.001, 1.0, "mm")
MACHINING_TARGET_SPACING_MM = Range("offline target spacing", 0.1, 50.0, "mm")
# Stocks of a variation sweep per configuration, and local worker processes.
MACHINING_VARIATIONS = Range("variations", 0, 1000, integer=True)
MACHINING_WORKERS = Range("workers", 1, 256, integer=True)

# --- the real part (real_part.PartDeviation) and teaching by pointing (guide_proposal) ------
# A fixture places a casting within a few mm and a degree or two; castings hold their walls
# within tenths of a mm of the CAD (issue 15).
FIXTURE_SHIFT_MM = Range("fixture shift", 0.0, 5.0, "mm")
FIXTURE_ROTATION_DEG = Range("fixture rotation", 0.0, 3.0, "deg")
WALL_OFFSET_MM = Range("casting wall offset", 0.0, 2.0, "mm")
BURR_COUNT = Range("burrs", 0, 50, integer=True)
BURR_HEIGHT_MM = Range("burr height", 0.0, 1.0, "mm")
# A proposed guide point: 1 mm off the wall, 3 mm above the floor where its own height fails.
WALL_GAP_MM = Range("gap to the wall", 0.2, 5.0, "mm", default=1.0)
MACHINING_HEIGHT_MM = Range("machining height above the floor", 0.5, 50.0, "mm", default=3.0)
