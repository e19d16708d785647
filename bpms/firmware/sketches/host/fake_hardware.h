// Host-side fake hardware for the BPMS firmware: a simulated clock, serial wires with byte
// timing, the arbiter's multiplexers and RN-41 (with CTS), and cluster boards whose I2C bus
// carries a TCA9548A and three scripted SEN-10724 sticks. Host code: the STL is fine here.
#ifndef BPMS_FAKE_HARDWARE_H
#define BPMS_FAKE_HARDWARE_H

#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "bpms_core/arbiter_logic.h"
#include "bpms_core/cluster_logic.h"
#include "bpms_core/sensors.h"

namespace sim {

class World;

// ---------------------------------------------------------------- clock
class SimClock : public bpms::Clock {
public:
    explicit SimClock(World& world) : world_(world) {}
    uint32_t micros() override;            // charges `tick_us` of CPU time per call
    void delay_micros(uint16_t us) override;
    uint32_t tick_us = 4;                  // Arduino's micros() resolution at 16 MHz
private:
    World& world_;
};

// ---------------------------------------------------------------- I2C
enum class Fault { NONE, NACK, ALL_FF, SHORT_READ, OUT_OF_RANGE };

// One chip: a register file with an auto-incrementing pointer. Reading the data registers
// takes a new sample, whose chip-axis values come from `values(sample)`; `fault(sample)` can
// spoil that read. `sample` counts data-read attempts from 0.
class FakeChip {
public:
    FakeChip(uint8_t addr, bpms::Sensor kind);
    bool write(const uint8_t* data, uint8_t n);
    uint8_t read(uint8_t* data, uint8_t n);

    uint8_t addr;
    bpms::Sensor kind;
    bool present = true;  // false: NACKs everything (unplugged)
    uint8_t regs[256] = {};
    std::vector<std::pair<uint8_t, uint8_t>> writes;  // (register, value) log
    uint32_t samples = 0;
    std::function<void(uint32_t sample, int16_t chip[3])> values;
    std::function<Fault(uint32_t sample)> fault;

private:
    uint8_t data_reg() const;
    void load_sample();
    uint8_t ptr_ = 0;
    Fault pending_ = Fault::NONE;
};

class FakeI2cBus : public bpms::I2cBus {
public:
    FakeI2cBus();
    bool write(uint8_t addr, const uint8_t* data, uint8_t n) override;
    uint8_t read(uint8_t addr, uint8_t* data, uint8_t n) override;
    FakeChip& chip(uint8_t slot, bpms::Sensor s) { return *chips_[slot * 3 + s]; }

    bool mux_present = true;
    uint8_t mux_mask = 0;
    bool stick_connected[3] = {true, true, true};  // false: the whole stick is gone

private:
    FakeChip* route(uint8_t addr);
    std::vector<std::unique_ptr<FakeChip>> chips_;
};

class FakeLed : public bpms::DigitalOut {
public:
    void set(bool on) override {
        if (on != state) ++changes;
        state = on;
    }
    bool state = false;
    int changes = 0;
};

// ---------------------------------------------------------------- serial wires
struct TimedByte {
    uint64_t time;  // world time (us) at which the byte has fully arrived
    uint8_t value;
    int channel;    // arbiter TX only: channel selected when the byte was written
};

// A cluster board's USART.
class ClusterPort : public bpms::SerialPort {
public:
    ClusterPort(World& world, int index) : world_(world), index_(index) {}
    int available() override { return static_cast<int>(rx.size()); }
    int read() override;
    void write(const uint8_t* data, uint16_t n) override;
    void flush() override;
    void idle() override { ++idles; }  // the world runs loop() only when a byte is there
    std::deque<uint8_t> rx;
    uint32_t idles = 0;
    std::deque<TimedByte> tx;
    int max_reply_bytes = -1;  // >= 0: every write is cut after that many bytes (broken wire)
    uint64_t reply_delay_us = 0;  // a slow board: its bytes start this long after the write

private:
    World& world_;
    int index_;
};

// The arbiter's USART plus its board (multiplexers, RN-41 CTS, battery ADC).
class ArbiterPort : public bpms::SerialPort, public bpms::ArbiterBoard {
public:
    explicit ArbiterPort(World& world) : world_(world) {}
    int available() override;
    int read() override;
    void write(const uint8_t* data, uint16_t n) override;
    void flush() override;
    // Sleeps until a byte is received or the next timer tick (every TICK_US of world time).
    void idle() override;
    static const uint64_t TICK_US = 1024;
    uint32_t idles = 0;
    void select_channel(uint8_t channel) override;
    void hold_radio(bool hold) override;
    uint16_t read_battery_adc() override { return battery_adc; }

    static const size_t RX_BUFFER = 64, TX_BUFFER = 64;  // HardwareSerial's buffers
    std::deque<uint8_t> rx;
    std::deque<TimedByte> tx;
    int channel = RADIO;
    bool held = false;
    uint16_t battery_adc = 507;  // 3.27 V with the default divider
    uint64_t rx_overflows = 0;
    std::function<void(int channel)> on_select;  // test hook, called after each switch

private:
    World& world_;
};

// ---------------------------------------------------------------- the suit
struct ClusterBoard {
    ClusterBoard(World& world, int index);
    FakeI2cBus bus;
    ClusterPort port;
    FakeLed led;
    bpms::ClusterLogic logic;
    uint32_t polls_seen = 0;  // poll bytes that reached the board
    std::function<bool(uint32_t poll)> dead;  // true: the board ignores that poll (0-based)
    std::vector<uint64_t> poll_times;          // arrival of each poll byte it answered
};

struct RadioByte {
    uint64_t time;
    uint8_t value;
};

class World {
public:
    // clock_start: value of the arbiter's micros() at world time 0 (tests wrap-around).
    explicit World(uint32_t clock_start = 0);
    // Power on: every cluster configures its sensors and takes its first reading, then the
    // arbiter starts. Script the chips before this.
    void boot();

    // The world's state catches up with `now` (bytes arrive, clusters run).
    void advance(uint64_t us);
    void process();

    // Host side of the RN-41: a byte the host sends at the current time.
    void host_send(uint8_t byte);
    // Run the arbiter's loop until `done` holds or `max_us` of world time has passed.
    // Returns true when `done` held.
    bool run_until(const std::function<bool()>& done, uint64_t max_us);
    void run_for(uint64_t us);

    // Bytes the radio received (host's view), and helpers.
    std::vector<uint8_t> radio_bytes() const;
    std::vector<uint8_t> take_radio_bytes();  // and clear

    // Wire timing: microseconds per byte (10 = 1 Mbaud).
    uint64_t radio_byte_us = 10;    // arbiter -> RN-41 (slow = Bluetooth back-pressure)
    uint64_t cluster_byte_us = 10;  // both directions between arbiter and clusters
    uint64_t host_byte_us = 10;     // RN-41 -> arbiter

    uint64_t now = 0;
    uint32_t clock_start;
    SimClock clock;
    ArbiterPort arbiter_port;
    FakeLed arbiter_led;
    std::vector<std::unique_ptr<ClusterBoard>> clusters;
    std::unique_ptr<bpms::ArbiterLogic> arbiter;

    std::vector<RadioByte> radio_in;   // bytes that reached the RN-41 (sent to the host)
    std::deque<uint8_t> host_pending;  // bytes inside the RN-41 waiting for CTS
    uint64_t host_bytes_lost = 0;      // host bytes sent while the USART listened elsewhere
    uint64_t misrouted_bytes = 0;      // arbiter bytes that left after the mux had moved
    uint64_t cluster_bytes_lost = 0;   // cluster bytes sent while not selected
    std::optional<uint64_t> host_inflight_time;  // RN-41 -> arbiter byte on the wire
    uint8_t host_inflight_value = 0;

private:
    void deliver_arbiter_byte(const TimedByte& b);
};

// Scripted chip-axis value used by the scenarios (also reproduced by tests/test_firmware.py):
// deterministic, inside each chip's valid range, exercising signs and both bytes.
int16_t scripted_value(int imu, int sensor, int axis, uint32_t sample);

// Install scripted_value on every chip of every cluster.
void script_all(World& world);

}  // namespace sim

#endif  // BPMS_FAKE_HARDWARE_H
