// BPMS wire protocol (docs/frame-format.md, docs/suit.md): constants and pure helpers shared by the cluster and
// arbiter sketches and by the host test build.
//
// Plain C++11 for the AVR: no heap, no STL, no exceptions; only <stdint.h>/<string.h>.
#ifndef BPMS_PROTOCOL_H
#define BPMS_PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

namespace bpms {

// --- frame layout (docs/frame-format.md) ---------------------------------------------------------------
const uint8_t N_CLUSTERS = 6;
const uint8_t IMUS_PER_CLUSTER = 3;
const uint8_t SENSORS_PER_IMU = 3;  // 0 accel, 1 mag, 2 gyro
const uint8_t AXES = 3;
const uint8_t CHANNELS_PER_IMU = SENSORS_PER_IMU * AXES;         // ax ay az mx my mz gx gy gz
const uint8_t IMU_BYTES = CHANNELS_PER_IMU * 2;                  // 18
const uint8_t CLUSTER_DATA_BYTES = IMUS_PER_CLUSTER * IMU_BYTES;  // 54
const uint8_t CLUSTER_REPLY_BYTES = CLUSTER_DATA_BYTES + 2;      // 56 (data + error word)
const uint16_t FRAME_BYTES = 2 + N_CLUSTERS * CLUSTER_REPLY_BYTES + 2;  // 340
const uint8_t START_MARK[2] = {'$', '#'};
const uint8_t END_MARK[2] = {'#', '$'};

enum Sensor : uint8_t { ACCEL = 0, MAG = 1, GYRO = 2 };

// Error word: bit 3*slot + sensor set when that sensor failed; bits 9..15 are zero.
const uint16_t ERROR_ALL = 0x01FF;
inline uint16_t error_bit(uint8_t slot, uint8_t sensor) {
    return static_cast<uint16_t>(1u << (slot * SENSORS_PER_IMU + sensor));
}

// --- arbiter commands (docs/suit.md) -------------------------------------------------------------
const uint8_t CMD_STREAM = 0x00;
const uint8_t CMD_BATTERY = 0x01;
const uint8_t CMD_IDENTIFY = 0x02;
const uint8_t POLL_BYTE = 0x00;  // what the arbiter sends a cluster (content is ignored)
const uint8_t IDENT_REPLY[4] = {'B', 'P', 'M', 'S'};
const uint8_t BATTERY_REPLY_BYTES = 6;  // "V3.27\n"

// --- timing -------------------------------------------------------------------------------
const uint32_t FRAME_PERIOD_US = 20000;  // 50 Hz

// --- big-endian packing -------------------------------------------------------------------
inline void put_be16(uint8_t* out, uint16_t v) {
    out[0] = static_cast<uint8_t>(v >> 8);
    out[1] = static_cast<uint8_t>(v & 0xFF);
}
inline void put_be16s(uint8_t* out, int16_t v) { put_be16(out, static_cast<uint16_t>(v)); }
inline uint16_t get_be16(const uint8_t* in) {
    return static_cast<uint16_t>((static_cast<uint16_t>(in[0]) << 8) | in[1]);
}
inline int16_t get_be16s(const uint8_t* in) { return static_cast<int16_t>(get_be16(in)); }
inline int16_t get_le16s(const uint8_t* in) {
    return static_cast<int16_t>(static_cast<uint16_t>(in[0]) | (static_cast<uint16_t>(in[1]) << 8));
}

// Two's-complement negation that saturates (-(-32768) would overflow int16).
inline int16_t negate_sat(int16_t v) {
    return v == -32768 ? static_cast<int16_t>(32767) : static_cast<int16_t>(-v);
}

// --- time ---------------------------------------------------------------------------------
// True when the wrapping 32-bit microsecond clock `now` has reached `deadline`. Valid while
// the two are less than 2^31 us (35 min) apart, so micros() wrapping every 71 min is harmless.
inline bool time_reached(uint32_t now, uint32_t deadline) {
    return static_cast<int32_t>(now - deadline) >= 0;
}

// --- battery --------------------------------------------------------------------------------
// Divider and reference assumptions (docs/firmware.md): cell -> 100k -> A0 -> 100k -> GND,
// ADC reference AVcc = 3.3 V regulated. V_cell = counts * VREF * (top+bottom)/bottom / 1024.
struct BatteryDivider {
    uint16_t vref_mv;     // ADC reference in millivolts
    uint16_t r_top;       // divider resistor from the cell to the ADC pin (any unit)
    uint16_t r_bottom;    // divider resistor from the ADC pin to ground (same unit)
};
const BatteryDivider DEFAULT_DIVIDER = {3300, 100, 100};
const uint8_t BATTERY_SAMPLES = 8;  // readings averaged per reply

// Cell voltage in millivolts from the SUM of `n` 10-bit ADC readings.
uint16_t battery_millivolts(uint32_t adc_sum, uint8_t n, const BatteryDivider& d);

// Writes exactly BATTERY_REPLY_BYTES bytes "V<d>.<dd>\n" (rounded to 10 mV, clamped to
// 0.00..9.99 V) into out.
void format_battery_reply(uint16_t millivolts, uint8_t out[BATTERY_REPLY_BYTES]);

}  // namespace bpms

#endif  // BPMS_PROTOCOL_H
