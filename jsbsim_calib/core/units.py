"""Unit constants. SI inside Python; JSBSim (English) units only at the XML and FDM boundary.

Multiply a value in the named unit by the constant to get SI, divide to go back:
``span_m = span_ft * FT``; ``span_ft = span_m / FT``.
"""
import math

FT = 0.3048                 # [m/ft]
IN = 0.0254                 # [m/in]
LBM = 0.45359237            # [kg/lb]
LBF = 4.4482216152605       # [N/lbf]
SLUG = LBF / FT             # [kg/slug]
KT = 1852.0 / 3600.0        # [m/s per knot]
FPM = FT / 60.0             # [m/s per ft/min]
HP = 745.69987158227        # [W/hp]  (mechanical horsepower)
G0 = 9.80665                # [m/s^2]
DEG = math.pi / 180.0       # [rad/deg]
US_GAL = 3.785411784e-3     # [m^3/US gal]
INHG = 3386.389             # [Pa/inHg]
RANKINE = 5.0 / 9.0         # [K/R]
LB_PER_GAL_AVGAS = 6.02     # [lb/US gal] JSBSim's AVGAS density (FGTank)

# ISA sea level
P0 = 101325.0               # [Pa]
T0 = 288.15                 # [K]
RHO0 = 1.225                # [kg/m^3]
R_AIR = 287.05287           # [J/(kg K)]
LAPSE = 0.0065              # [K/m] troposphere
GAMMA = 1.4

# Units accepted in human-written files, by dimension: name -> factor to SI.
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": IN, "ft": FT},
    "area": {"m2": 1.0, "ft2": FT**2, "in2": IN**2},
    "volume": {"m3": 1.0, "in3": IN**3, "L": 1e-3, "gal": US_GAL},
    "angle": {"deg": DEG, "rad": 1.0},
    "mass": {"kg": 1.0, "lb": LBM},
    "force": {"N": 1.0, "lbf": LBF},
    "power": {"W": 1.0, "hp": HP},
    "pressure": {"Pa": 1.0, "inHg": INHG},
    "speed": {"m/s": 1.0, "kt": KT, "ft/s": FT},
    "time": {"s": 1.0, "min": 60.0},
    "inertia": {"kg*m2": 1.0, "slug*ft2": SLUG * FT**2},
    "stiffness": {"N/m": 1.0, "lbf/ft": LBF / FT},
    "damping": {"N*s/m": 1.0, "lbf*s/ft": LBF / FT},
    "dimensionless": {"": 1.0},
}
