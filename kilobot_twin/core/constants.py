"""Kilobot constants and the controller constants we chose, each with its source.

Distances in metres, times in seconds, motor values in the Kilobot's 0-255 PWM units.
"""

#: Wheel surface speed at motor value 255 (6.0 cm/s), so a wheel runs at 6 cm/s x motor/255.
WHEEL_SPEED_MAX_M_S = 0.06
#: Distance between the two contact points (vibration legs) of a Kilobot.
WHEEL_SEPARATION_M = 0.025
#: Kilobot body radius (33 mm diameter); used for wall contact.
BODY_RADIUS_M = 0.0165
#: Motor values of the Kilobot library's calibrated defaults (kilo_straight_*, kilo_turn_*).
KILO_STRAIGHT_LEFT = 48
KILO_STRAIGHT_RIGHT = 48
KILO_TURN_LEFT = 77
KILO_TURN_RIGHT = 77
#: Nominal rate of the Kilobot's kilo_ticks counter.
TICK_HZ = 31.0
#: Highest ambient-light ADC reading (10-bit).
LIGHT_READING_MAX = 1023.0
#: Peak intensity of the authors' light cone (their simulator's units).
LIGHT_PEAK = 1024.0

# Motion commands shared by all behaviours (values stored in int8 arrays).
STOP, FORWARD, TURN_LEFT, TURN_RIGHT = 0, 1, 2, 3

# LED colours of the blink program.
LED_RED, LED_BLUE, LED_OFF = 0, 1, 2
