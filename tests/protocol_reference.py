"""Independent references for the wheel-board protocol tests (not the code under test)."""


def crc_bytewise(data: bytes) -> int:
    """CRC-16/CCITT-FALSE in the firmware's table-free byte-wise form (avr-libc's
    ``_crc_ccitt_update`` shape with init 0xFFFF): an independent reference for ``wheelproto``."""
    crc = 0xFFFF
    for b in data:
        x = ((crc >> 8) ^ b) & 0xFF
        x ^= x >> 4
        crc = ((crc << 8) ^ (x << 12) ^ (x << 5) ^ x) & 0xFFFF
    return crc
