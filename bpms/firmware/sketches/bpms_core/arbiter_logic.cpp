#include "arbiter_logic.h"

#include <string.h>

namespace bpms {

ArbiterLogic::ArbiterLogic(SerialPort& serial, ArbiterBoard& board, Clock& clock,
                           DigitalOut& stream_led, const BatteryDivider& divider)
    : serial_(serial), board_(board), clock_(clock), led_(stream_led), divider_(divider),
      streaming_(false), channel_(ArbiterBoard::RADIO), deadline_(0), queue_head_(0),
      queue_count_(0) {
    memset(&stats_, 0, sizeof stats_);
    memset(frame_, 0, sizeof frame_);
}

void ArbiterLogic::begin() {
    board_.hold_radio(true);
    board_.select_channel(ArbiterBoard::RADIO);
    channel_ = ArbiterBoard::RADIO;
    discard_rx();
    board_.hold_radio(false);
    led_.set(false);
}

void ArbiterLogic::loop() {
    take_host_bytes();
    if (streaming_) {
        if (queue_count_ == 0) {
            const uint32_t t = clock_.micros();
            if (!time_reached(t, deadline_)) {
                if (deadline_ - t > IDLE_MARGIN_US) serial_.idle();
                return;
            }
            // The sampling instant is the first poll, after the previous frame has left.
            serial_.flush();
            const uint32_t now = clock_.micros();
            if (now - deadline_ >= LATE_US) ++stats_.late_starts;
            if (now - deadline_ >= FRAME_PERIOD_US) {
                // A whole slot was lost: start a new grid here rather than sending a burst.
                deadline_ = now;
                ++stats_.resyncs;
            }
            deadline_ += FRAME_PERIOD_US;  // from the deadline, not from now: no drift
            send_frame();
            return;
        }
        // Any byte stops the stream between two frames (a frame is never cut short)...
        streaming_ = false;
        led_.set(false);
    }
    // ... and is then interpreted as a command.
    uint8_t command;
    if (pop_host(command)) {
        handle_command(command);
    } else if (!streaming_) {
        serial_.idle();  // until the host sends a byte
    }
}

void ArbiterLogic::handle_command(uint8_t command) {
    switch (command) {
        case CMD_STREAM:
            streaming_ = true;
            deadline_ = clock_.micros();  // first frame at once
            led_.set(true);
            break;
        case CMD_BATTERY: {
            uint32_t sum = 0;
            for (uint8_t i = 0; i < BATTERY_SAMPLES; ++i) sum += board_.read_battery_adc();
            uint8_t reply[BATTERY_REPLY_BYTES];
            format_battery_reply(battery_millivolts(sum, BATTERY_SAMPLES, divider_), reply);
            serial_.write(reply, sizeof reply);
            break;
        }
        case CMD_IDENTIFY:
            serial_.write(IDENT_REPLY, sizeof IDENT_REPLY);
            break;
        default:
            ++stats_.unknown_commands;
            break;
    }
}

void ArbiterLogic::send_frame() {
    frame_[0] = START_MARK[0];
    frame_[1] = START_MARK[1];
    for (uint8_t k = 0; k < N_CLUSTERS; ++k) poll_cluster(k, frame_ + 2 + k * CLUSTER_REPLY_BYTES);
    frame_[FRAME_BYTES - 2] = END_MARK[0];
    frame_[FRAME_BYTES - 1] = END_MARK[1];
    return_to_radio();
    serial_.write(frame_, FRAME_BYTES);
    ++stats_.frames;
}

void ArbiterLogic::poll_cluster(uint8_t cluster, uint8_t* out) {
    if (channel_ == ArbiterBoard::RADIO) leave_radio();
    serial_.flush();  // the previous poll byte must not follow us to this cluster
    board_.select_channel(cluster);
    channel_ = cluster;
    discard_rx();  // leftovers of a late reply from the previous cluster
    serial_.write(&POLL_BYTE, 1);
    const uint32_t t0 = clock_.micros();
    uint8_t n = 0;
    while (n < CLUSTER_REPLY_BYTES) {
        int c = serial_.read();
        if (c >= 0) {
            out[n++] = static_cast<uint8_t>(c);
        } else if (clock_.micros() - t0 >= CLUSTER_TIMEOUT_US) {
            break;
        }
    }
    if (n < CLUSTER_REPLY_BYTES) {  // silent or cut short: nothing of it can be trusted
        memset(out, 0, CLUSTER_DATA_BYTES);
        put_be16(out + CLUSTER_DATA_BYTES, ERROR_ALL);
        ++stats_.cluster_timeouts;
    }
}

void ArbiterLogic::leave_radio() {
    serial_.flush();          // the previous frame must reach the radio before the mux moves
    board_.hold_radio(true);  // the RN-41 keeps the host's bytes while we talk to clusters
    clock_.delay_micros(GUARD_US);
    take_host_bytes(/*all=*/true);
}

void ArbiterLogic::return_to_radio() {
    serial_.flush();
    board_.select_channel(ArbiterBoard::RADIO);
    channel_ = ArbiterBoard::RADIO;
    clock_.delay_micros(GUARD_US);
    discard_rx();  // a cluster byte that was in flight is not a host command
    board_.hold_radio(false);
}

void ArbiterLogic::take_host_bytes(bool all) {
    // Bytes beyond the queue's room wait in the USART's receive buffer (64 bytes) for a later
    // loop, one command per loop. Only before the multiplexer leaves the radio must the buffer
    // be emptied (what it receives next belongs to a cluster): then the overflow is dropped.
    while (all || queue_count_ < QUEUE_SIZE) {
        const int c = serial_.read();
        if (c < 0) break;
        if (queue_count_ == QUEUE_SIZE) {
            ++stats_.dropped_host_bytes;
            continue;
        }
        queue_[(queue_head_ + queue_count_) % QUEUE_SIZE] = static_cast<uint8_t>(c);
        ++queue_count_;
    }
}

void ArbiterLogic::discard_rx() {
    while (serial_.read() >= 0) {
    }
}

bool ArbiterLogic::pop_host(uint8_t& byte) {
    if (queue_count_ == 0) return false;
    byte = queue_[queue_head_];
    queue_head_ = static_cast<uint8_t>((queue_head_ + 1) % QUEUE_SIZE);
    --queue_count_;
    return true;
}

}  // namespace bpms
