"""Writes aircraft/octo25/octo25.xml: P4's octocopter's 16 engines, propellers and geometry from
the numbers below, declared once (aircraft/README.md gives where each comes from). The XML is the
artefact JSBSim loads; edit the numbers here and run ``python aircraft/tools/make_octo25.py``
(the rotor table of aircraft/octo25/navsim.yaml must follow a change of geometry or propeller)."""
import math
import sys
from pathlib import Path

OUT = sys.argv[1] if len(sys.argv) > 1 else str(Path(__file__).resolve().parents[1] / "octo25" / "octo25.xml")

R_ARM = 0.65          # m, centre to rotor axis
Z_HUB = 0.10          # m, arm plane above the CG (structural z up)
HALF_GAP = 0.075      # m, upper/lower rotor half spacing along the rotor axis
GAMMA = 10.0          # deg, rotor-axis tilt from the body normal, tangential, alternating
AZ0 = 22.5            # deg, arm 1 azimuth (clockwise from the nose seen from above)

# propeller: 13 x 4.5 in, two blades; C_T(J) = DJI_9450's shape scaled to C_T0 = 0.105 and
# the zero-thrust J 0.73 -> 0.53 (pitch/diameter 0.48 -> 0.35); C_P flat at 0.042
D_IN = 13.0
CT0, CP0 = 0.105, 0.042
DJI = [(0.0000, 0.1288), (0.0522, 0.1252), (0.1039, 0.1207), (0.1470, 0.1153), (0.1983, 0.1089),
       (0.2504, 0.1015), (0.3022, 0.0932), (0.3539, 0.0842), (0.4039, 0.0745), (0.4496, 0.0644),
       (0.5004, 0.0538), (0.5526, 0.0426), (0.6039, 0.0310), (0.6548, 0.0189), (0.7039, 0.0064),
       (0.7291, -0.0001)]
DJI_CP = [0.0666, 0.0628, 0.0595, 0.0567, 0.0542, 0.0520, 0.0498, 0.0471, 0.0440, 0.0402, 0.0358,
          0.0305, 0.0243, 0.0175, 0.0099, 0.0061]     # DJI_9450's C_POWER at the same J
JSCALE = 0.53 / 0.73
CT_TAB = [(j * JSCALE, ct * CT0 / 0.1288) for j, ct in DJI]
# descent / reverse inflow (J < 0): continue the first segment's slope, so that a small inflow of
# either sign changes the thrust antisymmetrically (no moments from a horizontal wind on the
# tilted rotors); flat beyond J = -0.3
SLOPE0 = (CT_TAB[1][1] - CT_TAB[0][1]) / (CT_TAB[1][0] - CT_TAB[0][0])
CT_TAB = [(j, CT0 + SLOPE0 * j) for j in (-0.3, -0.2, -0.1)] + CT_TAB
CP_TAB = [(j * JSCALE, cp * CP0 / 0.0666) for (j, _), cp in zip(DJI, DJI_CP)]
SLOPE0P = (CP_TAB[1][1] - CP_TAB[0][1]) / (CP_TAB[1][0] - CP_TAB[0][0])
CP_TAB = [(j, CP0 + SLOPE0P * j) for j in (-0.3, -0.2, -0.1)] + CP_TAB
PROP_IXX = 2.3e-4     # kg m2: (1/12) 0.025 kg (0.330 m)^2 plus the motor bell's share

MOTOR = dict(velocityconstant=240, coilresistance=0.10, noloadcurrent=0.6, maxvolts=44.4,
             deceleration_factor=0.0333)

# body drag areas (Cd A), m2, and rotor drag per rotor, N per (m/s) per (rad/s)
CDA_XY, CDA_Z = 0.20, 0.35
K_ROTOR_DRAG = 4.9e-4
M2FT2 = 1 / 0.3048 ** 2
K_LBF = K_ROTOR_DRAG * (2 * math.pi / 60) * 0.3048 / 4.4482216   # lbf per (rpm * ft/s)


def rotors():
    """(engine index, arm, 'upper'/'lower', body xyz (x fwd, y right, z down) m, axis, sense)."""
    g = math.radians(GAMMA)
    out = []
    for k in range(1, 9):
        psi = math.radians(AZ0 + 45.0 * (k - 1))
        s = 1 if k % 2 == 1 else -1          # odd arms tilt towards +psi (clockwise seen from above)
        axis = (-s * math.sin(g) * math.sin(psi), s * math.sin(g) * math.cos(psi), -math.cos(g))
        hub = (R_ARM * math.cos(psi), R_ARM * math.sin(psi), -Z_HUB)
        for level, sign in (("upper", 1), ("lower", -1)):
            # the pair sits on one vertical line at the arm's end (the 13 mm a shared shaft
            # tilted 10 deg would set them apart sideways is neglected), so each rotor's arm is
            # the horizontal line from the CG to it, as navsim.yaml's tilt_deg assumes
            pos = (hub[0], hub[1], hub[2] - sign * HALF_GAP)
            # P4: counter-clockwise (seen from above) = upper of arms 1,3,5,7 and lower of 2,4,6,8.
            # JSBSim sense +1 = clockwise seen from behind the disc = counter-clockwise from above.
            ccw = (k % 2 == 1) == (level == "upper")
            out.append((2 * (k - 1) + (0 if level == "upper" else 1), k, level, pos, axis,
                        1 if ccw else -1, psi, s))
    return out


def table(rows, fmt="{:8.4f} {:8.5f}"):
    return "\n".join("          " + fmt.format(a, b) for a, b in rows)


def engine_xml(i, k, level, pos, axis, sense, psi, s):
    pitch = 90.0 - GAMMA
    yaw = math.degrees(psi) + 90.0 * s
    yaw = (yaw + 180.0) % 360.0 - 180.0
    xs, ys, zs = -pos[0], pos[1], -pos[2]     # structural frame: x aft, y right, z up
    m = MOTOR
    return f"""
    <!-- engine {i}: arm {k} ({math.degrees(psi):.1f} deg) {level}, {'CCW' if sense > 0 else 'CW'} seen from above -->
    <engine name="arm{k}-{level}">
      <brushless_dc_motor name="octo25-motor">
        <velocityconstant> {m['velocityconstant']} </velocityconstant>
        <coilresistance> {m['coilresistance']} </coilresistance>
        <noloadcurrent> {m['noloadcurrent']} </noloadcurrent>
        <maxvolts> {m['maxvolts']} </maxvolts>
        <deceleration_factor> {m['deceleration_factor']} </deceleration_factor>
      </brushless_dc_motor>
      <thruster>
        <propeller name="octo25-13x4.5">
          <ixx unit="KG*M2"> {PROP_IXX} </ixx>
          <diameter unit="IN"> {D_IN} </diameter>
          <numblades> 2 </numblades>
          <constspeed> 0 </constspeed>
          <table name="C_THRUST" type="internal"> <tableData>
{table(CT_TAB)}
          </tableData> </table>
          <table name="C_POWER" type="internal"> <tableData>
{table(CP_TAB)}
          </tableData> </table>
        </propeller>
        <location unit="M"> <x> {xs:.4f} </x> <y> {ys:.4f} </y> <z> {zs:.4f} </z> </location>
        <orient unit="DEG"> <roll> 0 </roll> <pitch> {pitch:.1f} </pitch> <yaw> {yaw:.1f} </yaw> </orient>
        <sense> {sense} </sense>
        <p_factor> 0 </p_factor>
      </thruster>
    </engine>"""


def drag_axis(axis, cda_m2, velocity, rotor_drag):
    """One body axis's drag: the body's (quadratic in the airspeed), and with ``rotor_drag`` the
    rotors' (their speeds' sum times the air-relative ``velocity`` component)."""
    rotor = f"""
      <function name="aero/force/{axis}_rotor_drag">
        <product>
          <value> {-K_LBF:.4e} </value>
          <property>aero/rotor-rpm-sum</property>
          <property>velocities/{velocity}</property>
        </product>
      </function>""" if rotor_drag else ""
    return f"""    <axis name="{axis}">
      <function name="aero/force/{axis}_body_drag">
        <product>
          <value> {-0.5 * cda_m2 * M2FT2:.5f} </value>
          <property>atmosphere/rho-slugs_ft3</property>
          <property>velocities/vt-fps</property>
          <property>velocities/{velocity}</property>
        </product>
      </function>{rotor}
    </axis>
"""


def contact(name, typ, x, y, z, k, c, extra=""):
    return f"""    <contact type="{typ}" name="{name}">
      <location unit="M"> <x> {x:.3f} </x> <y> {y:.3f} </y> <z> {z:.3f} </z> </location>
      <static_friction> 0.8 </static_friction>
      <dynamic_friction> 0.5 </dynamic_friction>{extra}
      <spring_coeff unit="N/M"> {k} </spring_coeff>
      <damping_coeff unit="N/M/SEC"> {c} </damping_coeff>
    </contact>"""


def main():
    rs = rotors()
    rpm_props = "\n".join(f"          <property>propulsion/engine[{r[0]}]/propeller-rpm</property>" for r in rs)
    gear = []
    for name, x, y in (("SKID_LEFT_FRONT", -0.35, -0.30), ("SKID_RIGHT_FRONT", -0.35, 0.30),
                       ("SKID_LEFT_AFT", 0.35, -0.30), ("SKID_RIGHT_AFT", 0.35, 0.30)):
        gear.append(contact(name, "BOGEY", x, y, -0.45, 10000, 400,
                            "\n      <rolling_friction> 0.5 </rolling_friction>"
                            "\n      <max_steer unit=\"DEG\"> 0 </max_steer>"
                            "\n      <brake_group> NONE </brake_group>"
                            "\n      <retractable> 0 </retractable>"))
    for k in range(1, 9):
        psi = math.radians(AZ0 + 45.0 * (k - 1))
        gear.append(contact(f"ARM{k}_END", "STRUCTURE", -R_ARM * math.cos(psi), R_ARM * math.sin(psi),
                            Z_HUB - HALF_GAP, 10000, 400))
    engines = "".join(engine_xml(*r) for r in rs)
    drag_axes = "".join(drag_axis(a, cda, v, a != "Z") for a, cda, v in (
        ("X", CDA_XY, "u-aero-fps"), ("Y", CDA_XY, "v-aero-fps"), ("Z", CDA_Z, "w-aero-fps")))
    xml = f"""<?xml version="1.0"?>
<!--
  octo25: JSBSim model of P4's heavy-lift agricultural octocopter, 24.5 kg, eight arms with a
  coaxial pair of rotors at each arm's end (sixteen rotors).  Every number is explained in
  aircraft/README.md.  The sixteen engine blocks differ only in place, orientation and sense: an
  edit to one motor or propeller goes to all sixteen, and a change of place, tilt or spin to
  navsim.yaml's rotor table too.

  Structural frame (JSBSim): x aft, y right, z up, origin at the CG.
  Arms k = 1..8 at azimuth 22.5 + 45 (k-1) deg, clockwise from the nose seen from above, the
  rotor axes 0.65 m from the centre, the arm plane 0.10 m above the CG; upper and lower rotors
  0.15 m apart, one above the other, their axes parallel.
  Engines: 2(k-1) is arm k's upper rotor, 2(k-1)+1 its lower rotor.
  Spin (P4): counter-clockwise seen from above = upper of arms 1,3,5,7 and lower of 2,4,6,8
  (JSBSim sense +1); clockwise = the others (sense -1), so each arm's pair cancels its torque.
  Tilt (P4 gives 0 < gamma < 90 deg, adjacent axes opposite, no value): gamma = 10 deg about the
  arm, the thrust's horizontal part tangential, towards increasing azimuth on odd arms and
  decreasing azimuth on even arms; yaw comes from the odd/even thrust difference.
  Throttle: no flight control system; navsim writes fcs/throttle-cmd-norm[i] (0..1) per engine,
  JSBSim copies it to fcs/throttle-pos-norm[i]; the motor voltage is throttle x 44.4 V.
  Rotor speed: propulsion/engine[i]/propeller-rpm (rev/min).
-->
<fdm_config name="octo25" version="2.0" release="BETA"
            xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
            xsi:noNamespaceSchemaLocation="http://jsbsim.sourceforge.net/JSBSim.xsd">

  <fileheader>
    <author>navsim</author>
    <description>24.5 kg coaxial octocopter (P4), 8 arms x 2 tilted rotors, 13x4.5 in propellers</description>
    <version>1.0</version>
  </fileheader>

  <metrics>
    <!-- reference values only: the aerodynamics below use their own areas -->
    <wingarea unit="M2"> 1.0 </wingarea>
    <wingspan unit="M"> 1.63 </wingspan>
    <chord unit="M"> 1.0 </chord>
    <location name="AERORP" unit="M"> <x> 0 </x> <y> 0 </y> <z> 0 </z> </location>
    <location name="EYEPOINT" unit="M"> <x> 0 </x> <y> 0 </y> <z> 0 </z> </location>
    <location name="VRP" unit="M"> <x> 0 </x> <y> 0 </y> <z> 0 </z> </location>
  </metrics>

  <mass_balance>
    <ixx unit="KG*M2"> 2.4 </ixx>
    <iyy unit="KG*M2"> 2.3 </iyy>
    <izz unit="KG*M2"> 3.5 </izz>
    <ixy unit="KG*M2"> 0 </ixy>
    <ixz unit="KG*M2"> 0 </ixz>
    <iyz unit="KG*M2"> 0 </iyz>
    <emptywt unit="KG"> 24.5 </emptywt>
    <location name="CG" unit="M"> <x> 0 </x> <y> 0 </y> <z> 0 </z> </location>
  </mass_balance>

  <ground_reactions>
    <!-- two skids (four contact points, 0.45 m below the CG) and the arm ends -->
{chr(10).join(gear)}
  </ground_reactions>

  <propulsion>
    <!-- Sixteen brushless motors (Kv 240 rpm/V, 0.10 ohm, 0.6 A no-load, 12S 44.4 V) with
         13x4.5 in two-blade propellers, defined inline: C_T(J) and C_P(J) are JSBSim's DJI_9450
         curves scaled to static values 0.105 and 0.042 (figure of merit 0.63) and to a
         zero-thrust advance ratio of 0.53, continued to J < 0 (descent) with their slopes at J = 0.
         JSBSim takes J from the airspeed along each rotor's own axis. -->{engines}
  </propulsion>

  <aerodynamics>
    <!-- Body drag: Cd A = {CDA_XY} m2 horizontally, {CDA_Z} m2 vertically, quadratic in the airspeed.
         Rotor drag (blade flapping / induced drag, RotorPy's form): each rotor -k Omega v_h with
         k = {K_ROTOR_DRAG} N/(m/s)/(rad/s), in the body x-y plane; at hover speed the sixteen rotors
         give about 4.9 N per m/s. Both act at the CG and use the air-relative velocity, so wind
         pushes the vehicle. -->
    <function name="aero/rotor-rpm-sum">
      <description>sum of the sixteen rotor speeds, rpm</description>
      <sum>
{rpm_props}
      </sum>
    </function>
{drag_axes}    <!-- no aerodynamic moments (declared so that JSBSim knows the moment axes: body X, Y, Z) -->
    <axis name="ROLL"/>
    <axis name="PITCH"/>
    <axis name="YAW"/>
  </aerodynamics>

</fdm_config>
"""
    with open(OUT, "w") as f:
        f.write(xml)
    for r in rs:
        print(r[0], r[1], r[2], [round(v, 4) for v in r[3]], [round(v, 4) for v in r[4]], r[5])


if __name__ == "__main__":
    main()


KT = CT0 * 1.225 * (D_IN * 0.0254) ** 4 / (4 * math.pi ** 2)
KQ = CP0 * 1.225 * (D_IN * 0.0254) ** 5 / (2 * math.pi) ** 3


def yaml_rotors():
    """navsim.yaml's rotors: spin +1 = clockwise seen from above (= -JSBSim sense); tilt_deg about
    the arm, right-handed: odd arms +GAMMA, even arms -GAMMA."""
    lines = []
    for i, k, level, pos, axis, sense, psi, s in rotors():
        lines.append(f"  - {{position_m: [{pos[0]:7.4f}, {pos[1]:7.4f}, {pos[2]:7.4f}], spin: {-sense:2d}, "
                     f"tilt_deg: {s * GAMMA:5.1f}, thrust_coefficient: {KT:.4e}, torque_coefficient: {KQ:.4e}}}"
                     f"   # engine {i:2d}: arm {k} {level}")
    return "\n".join(lines)
