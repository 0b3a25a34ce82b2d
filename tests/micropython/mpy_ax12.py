# protocol/dynamixel/ax12.py under the real micropython binary (checks.py asserts, no pytest).
from protocol.dynamixel import ax12
from tests.micropython.checks import check, done, raises

new = ax12.defaults(ax12.EDITION_EMANUAL)
old = ax12.defaults(ax12.EDITION_ORIGINAL)
check(len(new) == ax12.TABLE_SIZE == 50, "table size")
check(ax12.get(new, ax12.MODEL_NUMBER_L, 2) == 12, "model number")
# The two editions differ exactly here (e-manual / original manual).
diff = [a for a in range(50) if new[a] != old[a]]
check(diff == [11, 13, 17, 18, 26, 27], "editions differ at %r" % diff)
check((new[11], old[11]) == (70, 85), "temperature limit")
check((new[13], old[13]) == (140, 190), "max voltage")
check((new[17], old[17], new[18], old[18]) == (36, 4, 36, 4), "alarm masks")
check((new[26], old[26]) == (1, 0), "compliance margin")
check(ax12.get(new, ax12.TORQUE_LIMIT, 2) == ax12.get(new, ax12.MAX_TORQUE, 2), "torque limit")
raises(lambda: ax12.defaults("third"), ValueError, "unknown edition accepted")

for a in range(50):
    f = ax12.owner(a)
    if f is not None:
        check(f[0] <= a < f[0] + f[2], "owner of %d" % a)
check(ax12.owner(10) is None and ax12.owner(31)[1] == "goal_position", "reserved / high byte")

# Units at the protocol boundary.
check(ax12.rad_to_position(0.0) == 512, "centre")
check(ax12.rad_to_position(-10.0) == 0 and ax12.rad_to_position(10.0) == 1023, "clamp")
for v in (0, 1, 100, 511, 512, 1000, 1023):
    check(ax12.rad_to_position(ax12.position_to_rad(v)) == v, "position round trip %d" % v)
for v in (1, 10, 300, 1023):
    check(ax12.rad_s_to_speed(ax12.speed_to_rad_s(v)) == v, "speed round trip %d" % v)
    check(ax12.rad_s_to_signed(ax12.signed_to_rad_s(v | 0x400)) == v | 0x400, "cw %d" % v)
# e-manual: "No Load Speed 59rpm (at 12V)"; Moving Speed 0 = no speed control
check(abs(ax12.speed_to_rad_s(0) - 59.0 * 2 * 3.141592653589793 / 60) < 1e-9, "speed 0")
check(abs(ax12.speed_to_rad_s(300) - 33.3 * 2 * 3.141592653589793 / 60) < 1e-9, "300 = 33.3 rpm")
check(ax12.rad_s_to_speed(0.0) == 1, "speed 0 never written (it means maximum)")
check(ax12.fraction_to_load(-0.5) == 0x400 | 512, "load direction bit")
check(ax12.baud_to_bps(1) == 1000000 and ax12.baud_to_bps(34) == 57142, "baud")
check(ax12.return_delay_us(250) == 500, "return delay")
print("speed_max_rad_s %.6f" % ax12.speed_to_rad_s(0))
print("unit_rpm_rad_s %.6f" % ax12.speed_to_rad_s(1))
print("position_1023_rad %.6f" % ax12.position_to_rad(1023))
print("voltage %.1f" % ax12.voltage_to_v(120))
done("ax12")
