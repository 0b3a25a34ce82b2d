# protocol/dynamixel/xl430.py under the real micropython binary: table, access, units.
from protocol.dynamixel import xl430 as xl
from tests.micropython.checks import check, done

t = xl.defaults(1000)
check(xl.get(t, xl.MODEL_NUMBER_L, 2) == 1060, "model number 1060")
check(xl.get(t, xl.GOAL_POSITION, 4, True) == 1000, "goal starts at the horn")
check(t[xl.RETURN_DELAY_TIME] == 250 and xl.return_delay_us(250) == 500, "return delay")
xl.put(t, xl.HOMING_OFFSET, 4, -5)
check(xl.get(t, xl.HOMING_OFFSET, 4, True) == -5, "signed round trip")
check(xl.OWNER[xl.GOAL_POSITION + 3][1] == "goal_position" and xl.OWNER[66] is None, "owner")
check(xl.rad_to_position(xl.position_to_rad(3072)) == 3072, "position units")
check(abs(xl.velocity_to_rad_s(265) - 6.355) < 0.01, "velocity limit 265 = 60.7 rpm")
check(xl.baud_to_bps(3) == 1000000 and xl.bps_to_baud(57600) == 1, "baud")
print("fields", len(xl.FIELDS), "table", xl.TABLE_SIZE)
done("xl430")
