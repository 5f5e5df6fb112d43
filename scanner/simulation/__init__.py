"""The simulated Texplorer2: physically plausible scans from a material library (docs/devices.md#simulator).

The material library is data (``scanner/data/materials.toml``, one table per material, set by hand); every
other material of the taxonomy is derived from its codes (:mod:`~scanner.simulation.derived`,
``scanner/data/material_classes.toml``). This package turns a material, a seed and a per-scan operator draw
into every channel of docs/database.md at its true rate, following the scanning procedure of
docs/operator.md#procedure one step at a time. Each simulated sensor has its own module:

======================  ==================  ============================================================
step                    module              what is synthesised
======================  ==================  ============================================================
``finger_tap``          ``accelerometer``   ``v_ft``: decaying contact resonances, frequency rising with
                                            stiffness
``finger_slide``        ``slides``          ``v_fs``, ``a_fs``, ``r_fs``: rest, then the finger slides over
                                            the surface; one contact excitation (``contact``) drives the
                                            ``accelerometer`` and the ``microphone``; ``reflectance``
``tool_tap``            ``accelerometer``   ``v_tt``: as the finger tap, through the steel tool tip
``tool_slide``          ``slides``          ``v_ts``, ``a_ts``, ``r_ts``: rest, then the tool tip slides
``static``              ``electrodes``,     ``m`` (metal electrodes) and ``dB`` (magnetometer), 1 s
                        ``magnetometer``
``thermal``             ``thermometer``     ``t_cool``: 10 s of MLX90614 readings after 3 s of Peltier heating
``friction``            ``force``           ``f_frn``, ``f_frt``: press, static peak, kinetic sliding, release
``press``               ``force``           ``f_press``: 4.0 mm indentation held, with relaxation
``fold``                ``flex``            ``f_fold``, ``alpha_f`` (absent when the operator skips it for a
                                            rigid sample)
``photos``              ``camera``          ``I_disp``, ``I_macro`` (4x lens), ``I_illu`` (flash):
                                            procedural textures (``textures``)
``tu4``                 ``tu4``             mass, volume, judged adhesive tack and yielding
======================  ==================  ============================================================

Every step function has the signature ``step(material, rng, operator)`` and returns that step's arrays
(:mod:`~scanner.simulation.steps`), so a simulated device can produce one step at a time. Vibration is
modelled as the tip following a surface height profile (:mod:`~scanner.simulation.surface`). The material
model and its library are :mod:`~scanner.simulation.materials`, the operator's draw and the physical sample
:mod:`~scanner.simulation.variability`, whole scans :mod:`~scanner.simulation.scans`.

Sensors are modelled at the level the host sees them: the ADXL335 through the DAQ (1.65 V zero,
0.330 V/g, 16-bit over +-10 V, +-3.6 g), FSR volts mapped through paper eq. (1), the MLX90614's 0.02 degC
steps, the MAG3110's 0.1 uT steps and 16-bit audio.

Two modules are not imported here: :mod:`~scanner.simulation.database` stores simulated scans in a
database (``synthetic_database``), so the simulated devices, which use this package, do not depend on
storage; :mod:`~scanner.simulation.recordings` simulates the related methods' sensors.
"""

from scanner.simulation.accelerometer import finger_tap, tool_tap
from scanner.simulation.camera import PHOTO_FOV_MM, photos
from scanner.simulation.derived import is_hand_set, material_for_label, material_named
from scanner.simulation.flex import fold
from scanner.simulation.force import friction_slide, press
from scanner.simulation.materials import (
    MAGNETIC_TYPES,
    TEXTURES,
    Material,
    SimulationError,
    UnknownMaterialError,
    load_materials,
)
from scanner.simulation.scans import SIMULATOR, sample_id_of, scan_seed, synthetic_scan, synthetic_scans
from scanner.simulation.slides import finger_slide, tool_slide
from scanner.simulation.steps import STEP_FUNCTIONS, STEPS, static_touch
from scanner.simulation.surface import FINGER, TOOL, Tip, contact_frequency_hz
from scanner.simulation.thermometer import thermal
from scanner.simulation.tu4 import tu4
from scanner.simulation.variability import OperatorDraw, draw_operator, sample_of

__all__ = [
    "FINGER", "MAGNETIC_TYPES", "PHOTO_FOV_MM", "SIMULATOR", "STEPS", "STEP_FUNCTIONS", "TEXTURES", "TOOL",
    "Material", "SimulationError", "SimulationError", "OperatorDraw", "SimulationError", "Tip",
    "UnknownMaterialError", "contact_frequency_hz", "draw_operator", "finger_slide", "finger_tap", "fold",
    "friction_slide", "is_hand_set", "material_for_label", "material_named",
    "load_materials", "photos", "press", "sample_id_of", "sample_of", "scan_seed", "static_touch",
    "synthetic_scan", "synthetic_scans", "thermal", "tool_slide", "tool_tap", "tu4",
]
