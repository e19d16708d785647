#include "cluster_logic.h"

#include <string.h>

#include "sensors.h"

namespace bpms {

ClusterLogic::ClusterLogic(I2cBus& bus, SerialPort& serial, DigitalOut& error_led)
    : bus_(bus), serial_(serial), led_(error_led), configured_(0) {
    memset(reply_, 0, sizeof reply_);
    put_be16(reply_ + CLUSTER_DATA_BYTES, ERROR_ALL);
}

void ClusterLogic::begin() {
    configured_ = 0;
    sample();  // configures every sensor on the way (configured_ is empty)
}

void ClusterLogic::loop() {
    if (serial_.available() <= 0) {
        serial_.idle();  // until the next poll byte (or the timer tick)
        return;
    }
    while (serial_.read() >= 0) {
    }
    serial_.write(reply_, CLUSTER_REPLY_BYTES);  // fits the 64-byte TX buffer: returns at once
    sample();
}

void ClusterLogic::sample() {
    uint16_t errors = 0;
    for (uint8_t slot = 0; slot < IMUS_PER_CLUSTER; ++slot) {
        uint8_t* imu = reply_ + slot * IMU_BYTES;
        bool connected = mux_select(bus_, slot);
        for (uint8_t s = 0; s < SENSORS_PER_IMU; ++s) {
            const Sensor sensor = static_cast<Sensor>(s);
            const uint16_t bit = error_bit(slot, s);
            uint8_t* out = imu + s * AXES * 2;
            int16_t chip[AXES];
            bool ok = connected;
            if (ok && !(configured_ & bit)) {
                ok = sensor_init(bus_, sensor);  // first use, or again after a failure
                if (ok) configured_ |= bit;
            }
            ok = ok && sensor_read(bus_, sensor, chip);
            if (ok) {
                int16_t board[AXES];
                apply_axis_map(AXIS_MAPS[s], chip, board);
                for (uint8_t a = 0; a < AXES; ++a) put_be16s(out + 2 * a, board[a]);
            } else {
                memset(out, 0, AXES * 2);
                errors |= bit;
                // A chip that failed may have been reset (power glitch, loose cable): configure
                // it again before its next read.
                if (connected) configured_ &= static_cast<uint16_t>(~bit);
            }
        }
    }
    put_be16(reply_ + CLUSTER_DATA_BYTES, errors);
    led_.set(errors != 0);
}

}  // namespace bpms
