"""The Dynamixel XM430-W350 control table (Protocol 2.0) as `esnap deploy` uses it: the one place
that names an address. The virtual bus of the simulated rig answers the same addresses."""

MODEL_NUMBER = (0, 2)  # (address, bytes)
OPERATING_MODE = (11, 1)
MAX_POSITION_LIMIT = (48, 4)
MIN_POSITION_LIMIT = (52, 4)
TORQUE_ENABLE = (64, 1)
HARDWARE_ERROR_STATUS = (70, 1)
BUS_WATCHDOG = (98, 1)  # unit 20 ms; 0 disables, -1 (0xFF) after it fired
GOAL_POSITION = (116, 4)
PRESENT_CURRENT = (126, 2)  # signed, unit 2.69 mA
PRESENT_VELOCITY = (128, 4)
PRESENT_POSITION = (132, 4)  # signed in extended position mode
# one sync read covers current, velocity and position (126..135)
PRESENT_BLOCK = (126, 10)

XM430_W350 = 1020  # model number
EXTENDED_POSITION_MODE = 4
WATCHDOG_UNIT_MS = 20
CURRENT_UNIT_MA = 2.69
ALERT_BIT = 0x80  # status packet error byte: a hardware error is latched (read address 70)
# Baud Rate (address 8): the rates the servo can be set to.
BAUD_RATES = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
# dynamixel-sdk 4.1.0's PortHandler.setBaudRate refuses 4.5 Mbps (not among its termios rates),
# and only after the port is open: refused before it instead.
SDK_CANNOT_SET = (4_500_000,)


def signed(value: int, nbytes: int) -> int:
    """Two's complement of an unsigned register value."""
    bits = 8 * nbytes
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


def unsigned(value: int, nbytes: int) -> int:
    return int(value) & ((1 << (8 * nbytes)) - 1)
