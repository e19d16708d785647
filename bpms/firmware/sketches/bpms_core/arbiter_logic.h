// Arbiter board logic (dissertation 2.3.1.3, docs/suit.md): command bytes from the host, polling of
// the six clusters through the serial multiplexer, the 340-byte frame every 20 ms.
#ifndef BPMS_ARBITER_LOGIC_H
#define BPMS_ARBITER_LOGIC_H

#include <stdint.h>

#include "hal.h"
#include "protocol.h"

namespace bpms {

struct ArbiterStats {
    uint32_t frames;            // frames sent
    uint32_t cluster_timeouts;  // cluster replies replaced by zeros + ERROR_ALL
    uint32_t resyncs;           // frames started a whole period or more late (grid re-anchored)
    uint32_t late_starts;       // frames started >= LATE_US after their deadline (overrun)
    uint32_t unknown_commands;  // bytes other than 0x00..0x02 received while idle
    uint32_t dropped_host_bytes;  // host bytes lost: queue and receive buffer full at a poll
};

class ArbiterLogic {
public:
    // A cluster must deliver its 56 bytes within this time of the poll (a healthy one needs
    // ~0.6 ms at 1 Mbaud). Six timeouts (15 ms) plus the frame (3.4 ms) still fit in 20 ms.
    static const uint16_t CLUSTER_TIMEOUT_US = 2500;
    // Time for a byte already on the wire to land after a mux switch or a CTS change.
    static const uint8_t GUARD_US = 50;
    // A frame starting this late means the previous one overran its 20 ms.
    static const uint16_t LATE_US = 1000;
    // The CPU sleeps between frames only while the deadline is further away than this: the
    // timer tick that wakes it comes every 1024 us, so the frame still starts on time.
    static const uint16_t IDLE_MARGIN_US = 1100;

    ArbiterLogic(SerialPort& serial, ArbiterBoard& board, Clock& clock, DigitalOut& stream_led,
                 const BatteryDivider& divider = DEFAULT_DIVIDER);

    void begin();  // connect the USART to the radio and let it talk
    void loop();   // call repeatedly; never blocks longer than one frame; sleeps when idle

    bool streaming() const { return streaming_; }
    const ArbiterStats& stats() const { return stats_; }

private:
    void handle_command(uint8_t command);
    void send_frame();
    void poll_cluster(uint8_t cluster, uint8_t* out);
    void leave_radio();
    void return_to_radio();
    void take_host_bytes(bool all = false);
    void discard_rx();
    bool pop_host(uint8_t& byte);

    SerialPort& serial_;
    ArbiterBoard& board_;
    Clock& clock_;
    DigitalOut& led_;
    BatteryDivider divider_;
    ArbiterStats stats_;
    bool streaming_;
    uint8_t channel_;
    uint32_t deadline_;  // start time of the next frame (micros)
    static const uint8_t QUEUE_SIZE = 8;
    uint8_t queue_[QUEUE_SIZE];  // host bytes not yet interpreted
    uint8_t queue_head_;
    uint8_t queue_count_;
    uint8_t frame_[FRAME_BYTES];
};

}  // namespace bpms

#endif  // BPMS_ARBITER_LOGIC_H
