#!/usr/bin/env python3
"""Writes the hand-made binary seeds of the MCU fuzz targets (corpus/mcu_host, corpus/mcu_device).
The operations are those listed at the top of fuzz_mcu_host.cpp and fuzz_mcu_device.cpp.
Usage: fuzz/make_seeds.py   (rewrites the files it owns; other files in those folders stay)."""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def varint(v):
    out = bytearray()
    while True:
        b = v & 0x7F
        v >>= 7
        out.append(b | (0x80 if v else 0))
        if not v:
            return bytes(out)


def zz(v):
    return varint((v << 1) ^ (v >> 63) if v >= 0 else ((-v) << 1) - 1)


def crc16(data):  # CRC16-CCITT (drivers/protocol/crc16.hpp)
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def frame(flags, seq, ack, payload):
    body = bytes([len(payload), flags]) + struct.pack('<HH', seq, ack) + payload
    c = crc16(body)
    return b'\x7e' + body + bytes([c >> 8, c & 0xFF])


def op_msg(payload):       # op 0 in both targets
    return bytes([0, len(payload)]) + payload


def op_raw(data):          # op 1
    return bytes([1, len(data)]) + data


def op_frame(flags, seq, ack, payload):  # op 2
    return bytes([2, flags]) + struct.pack('<HH', seq, ack) + bytes([len(payload)]) + payload


def op_time(t):            # op 3
    return bytes([3, t])


# device -> host messages
def identify_response(version=1, hz=20_000_000, axis=0, name=b'mcu'):
    return bytes([0x81]) + struct.pack('<H', version) + varint(hz) + bytes([axis, len(name)]) + name


def status(clock, flags, axes):
    out = bytes([0x87]) + varint(clock) + bytes([flags, len(axes)])
    for steps, pos, queued, h in axes:
        out += varint(steps) + zz(pos) + varint(queued) + varint(h)
    return out


def encoder_report(axis, first, period, counts):
    out = bytes([0x88, axis]) + varint(first) + varint(period) + varint(len(counts)) + zz(counts[0])
    for a, b in zip(counts, counts[1:]):
        out += zz(b - a)
    return out


def error_report(code, clock, detail):
    return bytes([0x89, code]) + varint(clock) + zz(detail)


def run_body(first_clock, runs):
    out = varint(first_clock)
    prev = 0
    for count, interval, add, direction in runs:
        out += varint((count << 1) | (1 if direction < 0 else 0)) + zz(interval - prev) + zz(add)
        prev = interval + (count - 1) * add
    return out


def host_seeds():
    s = {}
    s['session'] = (op_msg(identify_response()) + op_time(20) + bytes([5, 1, 0, 0]) + op_time(20) +
                    bytes([5, 1, 3, 0]) + bytes([4, 1, 0, 40]) + run_body(30000, [(10, 2000, -5, 1), (5, 1950, 0, -1)]).ljust(40, b'\0') +
                    op_msg(status(123456, 1, [(15, 5, 0, 0xDEADBEEF)])) +
                    op_msg(encoder_report(0, 1000, 20000, [0, 3, 7, 12, 20])) +
                    bytes([4, 2, 1, 4, 4, 4, 5]) + op_time(200) + bytes([6, 0]))
    s['board'] = (op_msg(identify_response(axis=0x83, name=b'board')) +
                  op_msg(status(5, 3, [(1, -1, 2, 3), (4, 5, 6, 7), (0, 0, 0, 0)])) + op_time(255) + op_time(255))
    s['version_mismatch'] = op_msg(identify_response(version=7, name=b'old fw'))
    s['errors'] = (op_msg(identify_response()) + op_msg(error_report(2, 99, -40)) + op_msg(error_report(5, 1, 3)) +
                   op_msg(error_report(200, 2, 0)) + op_msg(bytes([0x42, 1, 2])))
    s['noise'] = (op_raw(bytes(range(0x70, 0x90))) + op_raw(frame(0x13, 0, 0, b'\x81')[:-1] + b'\x00') +
                  op_frame(0x13, 0, 1, identify_response()) + op_frame(0x01, 3, 0, b'\x87') +
                  op_frame(0x04, 0, 0, b'') + op_time(100))
    s['reconnect'] = (op_msg(identify_response()) + bytes([7, 1]) + op_time(200) + bytes([7, 0]) + op_time(200) +
                      op_time(200) + bytes([4, 0]) + op_msg(identify_response()) + op_time(50))
    s['encoder_flood'] = op_msg(identify_response()) + b''.join(
        op_msg(encoder_report(0, 1000 + 400000 * i, 20000, list(range(0, 40, 2)))) for i in range(12))
    s['stall'] = op_time(255) * 12
    # Protocol v2: loop reports and events (op 8: kind, axis, fields), then the host takes them (op 9).
    report = (bytes([8, 0, 0]) + struct.pack('<qB', 123456, 1) + struct.pack('<qq', 5_000_000, 4_990_000) +
              struct.pack('<ff', 10000.0, 2500.0) + struct.pack('<qI', 42, 1800) + struct.pack('<QQQQ', 10, 0, 1, 0))
    event = bytes([8, 1, 0, 3]) + struct.pack('<qqq', 200000, 4, 1_000_000)
    s['loop_v2'] = (op_msg(identify_response(version=2)) + op_time(20) + report + event + report +
                    bytes([9, 0, 9, 1, 9, 2, 3, 1, 2, 3]) + op_time(40))
    s['v1_device'] = op_msg(identify_response(version=1)) + op_time(10) + op_msg(identify_response(version=1)) + op_time(10)
    return s


def device_seeds():
    s = {}
    ident = bytes([5, 1, 0, 0x10, 0x27, 10, 0x88, 0x13])  # version 1, encoder every 10000 ticks, 10/report, watchdog 500000
    s['steps'] = (bytes([0]) + ident + bytes([6, 1]) + bytes([4, 0, 0x10, 0x27, 2, 9, 0xE8, 0x03, 0xFB, 4, 0xD0, 0x07, 0]) +
                  op_time(50) + bytes([7]) + op_time(200) + bytes([7]))
    s['board'] = (bytes([3]) + ident + bytes([6, 1]) +
                  b''.join(bytes([4, a, 0x64, 0, 1, 20, 0x2C, 0x01, 0]) for a in range(4)) + op_time(100) + bytes([7]))
    s['raw_messages'] = (bytes([0]) + op_msg(bytes([1, 1, 0])) + op_msg(bytes([2]) + varint(1000) + varint(5) + varint(0)) +
                         op_msg(bytes([3, 0]) + run_body(500, [(3, 100, 0, 1), (2, 100, 10, -1)])) +
                         op_msg(bytes([4]) + varint(77)) + op_msg(bytes([5, 1])) + op_msg(bytes([8])) +
                         op_msg(bytes([7])) + op_msg(bytes([6])) + op_msg(bytes([0x55])) + op_time(30))
    s['not_identified'] = bytes([1]) + op_msg(bytes([3, 0]) + run_body(5, [(1, 1, 0, 1)])) + op_msg(bytes([4, 1]))
    s['version_mismatch'] = bytes([0]) + bytes([5, 9, 0, 0, 0, 1, 0, 0])
    s['underrun_overlap'] = (bytes([0]) + ident + op_time(100) + op_msg(bytes([3, 0]) + run_body(10, [(5, 10, 0, 1)])) +
                             bytes([5, 1, 0, 0, 0, 5, 0, 0]) + bytes([4, 0, 0xFF, 0xFF, 1, 0, 0x10, 0, 0]) +
                             bytes([4, 0, 0, 0, 1, 0, 0x10, 0, 0]))
    s['watchdog'] = bytes([0]) + bytes([5, 1, 0, 0, 0, 1, 1, 0]) + bytes([6, 1]) + op_time(255) + op_time(255)
    ident2 = bytes([5, 2, 0, 0x10, 0x27, 10, 0x88, 0x13])  # as ident, protocol version 2
    targets = bytes([9, 0, 0xD0, 0x07, 7]) + bytes([0xE8, 0x03, 5, 0]) * 8  # 8 knots, 1 ms and 5 um apart
    s['loop_v2'] = (bytes([0]) + ident2 + bytes([6, 1]) + bytes([8, 0, 100, 0, 0]) + targets + op_time(30) +
                    bytes([7]) + op_time(100) + bytes([7]) + op_time(255))
    # Parameters that must be refused: period 0, kp NaN, report every tick.
    s['loop_v2_bad_params'] = (bytes([0]) + ident2 + bytes([8, 0, 0, 0, 3, 1, 0, 0, 0, 0, 4, 0, 0, 0xC0, 0x7F,
                                                          20, 1, 0, 0, 0]) + op_time(20) + bytes([7]))
    s['loop_v1_host'] = bytes([0]) + ident + bytes([8, 0, 0, 0, 0]) + targets + op_time(10)
    # Protocol v3 heaters (ops 12-14 are the op bytes 240-242): heater 0 full ADC range with a 0.1 s
    # confirmation timeout (set once, then left to trip); heater 1 a narrow range that the sweeping
    # ADC leaves (the MCU's own limit); a fan; SET_HEATER to a faulted heater; a bad configuration.
    ident3 = bytes([5, 3, 0, 0x10, 0x27, 10, 0x88, 0x13])
    cfg0 = bytes([240, 0, 0x88, 0x13, 0, 8, 0, 0, 0xFF, 0xFF, 0xA0, 0x86, 0x01, 0xFF, 0xFF])
    cfg1 = bytes([240, 1, 0x88, 0x13, 0, 4, 0x00, 0x10, 0x00, 0x20, 0, 0, 0, 0x00, 0x80])
    bad = bytes([240, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0])
    s['heaters_v3'] = (bytes([0]) + ident3 + cfg0 + cfg1 + bytes([241, 0, 0xFF, 0x7F, 241, 1, 0xFF, 0xFF]) +
                       bytes([242, 0, 0x00, 0x80]) + op_time(255) * 2 + bytes([241, 0, 0xFF, 0xFF]) +
                       op_time(255) * 3 + bytes([7, 241, 0, 0xFF, 0xFF]) + bad + op_time(50) + bytes([7]))
    s['heaters_v2_refused'] = bytes([0]) + ident2 + cfg0 + bytes([241, 0, 0xFF, 0xFF, 242, 1, 1, 1]) + op_time(20)
    s['noise'] = (bytes([2]) + op_raw(bytes(range(0x70, 0x90))) + op_frame(0x13, 0, 0, bytes([1, 1, 0])) +
                  op_frame(0x11, 5, 0, bytes([8])) + op_frame(0x04, 0, 3, b'') + op_time(10) + bytes([7]))
    return s


def write(folder, seeds):
    path = os.path.join(HERE, 'corpus', folder)
    os.makedirs(path, exist_ok=True)
    for name, data in seeds.items():
        with open(os.path.join(path, name), 'wb') as f:
            f.write(data)


if __name__ == '__main__':
    write('mcu_host', host_seeds())
    write('mcu_device', device_seeds())
