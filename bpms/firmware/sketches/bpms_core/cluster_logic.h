// Cluster board logic (dissertation 2.3.1.2, docs/suit.md): answer each poll with the reading
// stored at the previous poll, then read the three IMUs anew.
#ifndef BPMS_CLUSTER_LOGIC_H
#define BPMS_CLUSTER_LOGIC_H

#include <stdint.h>

#include "hal.h"
#include "protocol.h"

namespace bpms {

class ClusterLogic {
public:
    ClusterLogic(I2cBus& bus, SerialPort& serial, DigitalOut& error_led);

    // Configure every sensor and take the first reading (it is the reply to the first poll).
    void begin();

    // Call repeatedly. On a poll (any byte; a burst of bytes counts as one poll) send the
    // stored 56-byte reply, then sample anew, so every answer is one poll old. Between polls
    // the CPU sleeps in idle mode (the USART wakes it).
    void loop();

    // Read the three IMUs into the stored reply and drive the error LED.
    void sample();

    const uint8_t* reply() const { return reply_; }
    uint16_t error_word() const { return get_be16(reply_ + CLUSTER_DATA_BYTES); }

private:
    I2cBus& bus_;
    SerialPort& serial_;
    DigitalOut& led_;
    uint8_t reply_[CLUSTER_REPLY_BYTES];
    uint16_t configured_;  // bit per sensor, numbered as in the error word
};

}  // namespace bpms

#endif  // BPMS_CLUSTER_LOGIC_H
