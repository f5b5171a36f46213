"""What the firmware's numbers mean, for one-line error messages.

Uses ``firmware_protocol.grbl``'s tables when they exist (the device side owns
the codes); falls back to the short list below, from GRBL 1.1's documentation.
"""

__all__ = ["grbl_error", "grbl_alarm", "marlin_checksum"]

_ERRORS = {
    1: "G-code words consist of a letter and a value; letter was not found",
    2: "numeric value format is not valid or missing an expected value",
    3: "Grbl '$' system command was not recognized or supported",
    8: "Grbl '$' command cannot be used unless Grbl is IDLE",
    9: "G-code locked out during alarm or jog state",
    15: "jog target exceeds machine travel",
    20: "unsupported or invalid g-code command found in block",
    22: "feed rate has not yet been set or is undefined",
    24: "two G-code commands that both require the use of the XYZ axis words were detected",
    33: "the motion command has an invalid target",
}

_ALARMS = {
    1: "hard limit triggered; machine position is likely lost, re-homing is recommended",
    2: "G-code motion target exceeds machine travel (soft limit); position retained",
    3: "reset while in motion; position is likely lost, re-homing is recommended",
    4: "probe fail",
    5: "probe fail",
    6: "homing fail: reset during active homing cycle",
    7: "homing fail: safety door was opened during homing",
    8: "homing fail: pull off failed to clear the limit switch",
    9: "homing fail: could not find the limit switch",
    10: "homing fail: second switch not found",
}


def _table(name):
    try:
        from firmware_protocol import grbl
    except ImportError:
        return None
    return getattr(grbl, name, None)


def grbl_error(code):
    """``error:N`` as words."""
    table = _table("ERRORS") or _ERRORS
    text = table.get(code)
    if isinstance(text, (tuple, list)):
        text = text[-1]
    return f"error:{code} ({text})" if text else f"error:{code}"


def grbl_alarm(code):
    """``ALARM:N`` as words."""
    table = _table("ALARMS") or _ALARMS
    text = table.get(code)
    if isinstance(text, (tuple, list)):
        text = text[-1]
    return f"ALARM:{code} ({text})" if text else f"ALARM:{code}"


def marlin_checksum(text):
    """XOR of every byte of ``text`` (the part of a Marlin line before ``*``)."""
    value = 0
    for b in text.encode("ascii"):
        value ^= b
    return value
