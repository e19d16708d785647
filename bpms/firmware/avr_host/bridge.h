// The byte protocol between avr_suit (this C host) and bpms/firmware/avr_suit.py (Python).
// Little-endian throughout; the Python side packs the same layout with struct.
//
// stdin, once at start:
//   "BPMSAVR1", bridge_config_t, n_sensor_off x bridge_sensor_off_t,
//   n_bus_stuck x bridge_bus_stuck_t,
//   n_samples x 162 int16: [18 IMUs][accel, mag, gyro][chip x, y, z], chip-axis counts
// stdin, then any number of messages:
//   'H' u16 n, n bytes   bytes the host sent (to the RN-41, then to the arbiter as CTS allows)
//   'O' u8 imu, u8 sensor, u8 on   switch a sensor chip off (0) or on again (1), now
//   'Q'                  stop (the final status follows)
// stdout, messages:
//   'D' u16 n, n bytes   bytes the RN-41 received from the arbiter (for the host)
//   'S' u16 n, n bytes   a status, one JSON object (every simulated second, and a final one)
#ifndef BPMS_BRIDGE_H
#define BPMS_BRIDGE_H

#include <stdint.h>

#define BRIDGE_MAGIC "BPMSAVR1"
#define BRIDGE_VALUES_PER_SAMPLE (18 * 3 * 3)

enum {
    MSG_HOST_BYTES = 'H',
    MSG_SWITCH = 'O',
    MSG_QUIT = 'Q',
    MSG_RADIO_BYTES = 'D',
    MSG_STATUS = 'S',
};

#pragma pack(push, 1)
typedef struct {
    uint32_t n_samples;
    uint32_t battery_mv;       // cell voltage at power-up
    uint32_t drain_uv_per_h;   // linear drain (floor 2.6 V)
    uint8_t realtime;          // 1: never faster than real time; 0: as fast as the host can
    uint32_t n_sensor_off;
    uint32_t n_bus_stuck;
} bridge_config_t;

typedef struct {
    uint8_t imu;     // 0..17
    uint8_t sensor;  // 0 accel, 1 mag, 2 gyro
    uint32_t from_ms, to_ms;  // simulated time since power-up: the chip is off in [from, to)
} bridge_sensor_off_t;

typedef struct {
    uint8_t cluster;          // 0..5
    uint32_t from_ms, to_ms;  // the cluster's I2C bus is held (SDA low) in [from, to)
} bridge_bus_stuck_t;
#pragma pack(pop)

#endif  // BPMS_BRIDGE_H
