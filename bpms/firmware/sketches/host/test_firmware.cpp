// Host tests of the BPMS firmware logic against fake hardware (fake_hardware.h).
// A tiny harness: every TEST runs, failed checks are printed, the last line is
// "N passed, N failed" (tests, not checks); the exit status is non-zero on any failure.
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "bpms_core/protocol.h"
#include "bpms_core/sensors.h"
#include "host/fake_hardware.h"

namespace {

struct TestCase {
    const char* name;
    void (*fn)();
};
std::vector<TestCase>& registry() {
    static std::vector<TestCase> r;
    return r;
}
struct Register {
    Register(const char* name, void (*fn)()) { registry().push_back({name, fn}); }
};
int g_check_failures = 0;

#define TEST(name)                                  \
    void test_##name();                             \
    Register reg_##name(#name, &test_##name);       \
    void test_##name()

#define CHECK(cond)                                                             \
    do {                                                                        \
        if (!(cond)) {                                                          \
            ++g_check_failures;                                                 \
            std::printf("    %s:%d: CHECK(%s)\n", __FILE__, __LINE__, #cond);   \
        }                                                                       \
    } while (0)

#define CHECK_EQ(a, b)                                                                   \
    do {                                                                                 \
        long long va_ = static_cast<long long>(a), vb_ = static_cast<long long>(b);      \
        if (va_ != vb_) {                                                                \
            ++g_check_failures;                                                          \
            std::printf("    %s:%d: CHECK_EQ(%s, %s): %lld != %lld\n", __FILE__, __LINE__, \
                        #a, #b, va_, vb_);                                               \
        }                                                                                \
    } while (0)

using bpms::FRAME_BYTES;
using sim::World;

std::string str(const std::vector<uint8_t>& v) { return std::string(v.begin(), v.end()); }

// Expected board-order value: accel and gyro swap chip x and y (Razor AHRS SEN-10724 order).
int16_t expected(int imu, int sensor, int board_axis, uint32_t sample) {
    static const int src[3][3] = {{1, 0, 2}, {0, 1, 2}, {1, 0, 2}};
    return sim::scripted_value(imu, sensor, src[sensor][board_axis], sample);
}

struct Frame {
    int16_t raw[18][9];
    uint16_t error[6];
};

// Split a byte stream that must be exactly whole frames.
bool split_frames(const std::vector<uint8_t>& bytes, std::vector<Frame>& out) {
    if (bytes.size() % FRAME_BYTES) return false;
    for (size_t off = 0; off < bytes.size(); off += FRAME_BYTES) {
        const uint8_t* f = bytes.data() + off;
        if (f[0] != '$' || f[1] != '#' || f[338] != '#' || f[339] != '$') return false;
        Frame fr;
        for (int k = 0; k < 6; ++k) {
            const uint8_t* c = f + 2 + 56 * k;
            for (int slot = 0; slot < 3; ++slot)
                for (int ch = 0; ch < 9; ++ch)
                    fr.raw[3 * k + slot][ch] = bpms::get_be16s(c + 18 * slot + 2 * ch);
            fr.error[k] = bpms::get_be16(c + 54);
        }
        out.push_back(fr);
    }
    return true;
}

// Compare a frame's cluster k with scripted sample n (no errors expected).
bool cluster_matches(const Frame& f, int k, uint32_t n) {
    if (f.error[k] != 0) return false;
    for (int slot = 0; slot < 3; ++slot)
        for (int s = 0; s < 3; ++s)
            for (int a = 0; a < 3; ++a)
                if (f.raw[3 * k + slot][3 * s + a] != expected(3 * k + slot, s, a, n)) return false;
    return true;
}

bool frame_matches(const Frame& f, uint32_t n) {
    for (int k = 0; k < 6; ++k)
        if (!cluster_matches(f, k, n)) return false;
    return true;
}

// A booted, scripted suit.
struct Suit {
    explicit Suit(uint32_t clock_start = 0) : w(clock_start) {
        sim::script_all(w);
        w.boot();
    }
    sim::ClusterBoard& cluster(int k) { return *w.clusters[k]; }
    bool run_frames(uint32_t n, uint64_t max_us = 10000000) {
        const uint32_t target = w.arbiter->stats().frames + n;
        return w.run_until([&] { return w.arbiter->stats().frames >= target; }, max_us);
    }
    // Stop the stream (between two frames) and let the last frame reach the radio.
    void drain() {
        w.host_send(0x55);
        w.run_for(100000);
    }
    World w;
};

// ============================================================ protocol helpers
TEST(big_endian_packing) {
    uint8_t b[2];
    bpms::put_be16s(b, -2);
    CHECK_EQ(b[0], 0xFF);
    CHECK_EQ(b[1], 0xFE);
    bpms::put_be16(b, 0x1234);
    CHECK_EQ(b[0], 0x12);
    CHECK_EQ(b[1], 0x34);
    CHECK_EQ(bpms::get_be16s(b), 0x1234);
    const uint8_t le[2] = {0x00, 0x80};
    CHECK_EQ(bpms::get_le16s(le), -32768);
}

TEST(error_word_bits) {
    CHECK_EQ(bpms::error_bit(0, bpms::ACCEL), 0x001);
    CHECK_EQ(bpms::error_bit(0, bpms::GYRO), 0x004);
    CHECK_EQ(bpms::error_bit(1, bpms::MAG), 0x010);
    CHECK_EQ(bpms::error_bit(2, bpms::GYRO), 0x100);
    uint16_t all = 0;
    for (int slot = 0; slot < 3; ++slot)
        for (int s = 0; s < 3; ++s) all |= bpms::error_bit(slot, s);
    CHECK_EQ(all, bpms::ERROR_ALL);
}

TEST(frame_constants) {
    CHECK_EQ(bpms::CLUSTER_REPLY_BYTES, 56);
    CHECK_EQ(bpms::FRAME_BYTES, 340);
}

TEST(time_reached_across_wraparound) {
    CHECK(bpms::time_reached(100, 100));
    CHECK(!bpms::time_reached(99, 100));
    CHECK(bpms::time_reached(5, 0xFFFFFFF0u));   // after the wrap
    CHECK(!bpms::time_reached(0xFFFFFFF0u, 5));  // before the deadline that wrapped
}

TEST(axis_map_swaps_accel_and_gyro_xy) {
    const int16_t chip[3] = {1, -2, 3};
    int16_t board[3];
    bpms::apply_axis_map(bpms::AXIS_MAPS[bpms::ACCEL], chip, board);
    CHECK(board[0] == -2 && board[1] == 1 && board[2] == 3);
    bpms::apply_axis_map(bpms::AXIS_MAPS[bpms::MAG], chip, board);
    CHECK(board[0] == 1 && board[1] == -2 && board[2] == 3);
    bpms::apply_axis_map(bpms::AXIS_MAPS[bpms::GYRO], chip, board);
    CHECK(board[0] == -2 && board[1] == 1 && board[2] == 3);
    const bpms::AxisMap negated = {{0, 1, 2}, {-1, -1, 1}};
    const int16_t extreme[3] = {-32768, 5, 7};
    bpms::apply_axis_map(negated, extreme, board);
    CHECK(board[0] == 32767 && board[1] == -5 && board[2] == 7);  // saturates, no overflow
}

TEST(battery_conversion_and_format) {
    uint8_t r[6];
    const uint16_t mv = bpms::battery_millivolts(507u * 8, 8, bpms::DEFAULT_DIVIDER);
    CHECK(mv >= 3266 && mv <= 3269);  // 507 * 3.3 V * 2 / 1024 = 3.2678 V
    bpms::format_battery_reply(mv, r);
    CHECK(std::memcmp(r, "V3.27\n", 6) == 0);
    bpms::format_battery_reply(2600, r);
    CHECK(std::memcmp(r, "V2.60\n", 6) == 0);
    bpms::format_battery_reply(3594, r);  // rounds to the nearest 10 mV
    CHECK(std::memcmp(r, "V3.59\n", 6) == 0);
    bpms::format_battery_reply(3595, r);
    CHECK(std::memcmp(r, "V3.60\n", 6) == 0);
    bpms::format_battery_reply(0, r);
    CHECK(std::memcmp(r, "V0.00\n", 6) == 0);
    bpms::format_battery_reply(12000, r);  // clamped, still 6 bytes
    CHECK(std::memcmp(r, "V9.99\n", 6) == 0);
    bpms::format_battery_reply(65535, r);
    CHECK(std::memcmp(r, "V9.99\n", 6) == 0);
    CHECK_EQ(bpms::battery_millivolts(1023u * 8, 8, bpms::DEFAULT_DIVIDER), 6594);
    const bpms::BatteryDivider other = {1100, 100, 27};  // 1.1 V bandgap, 100k over 27k
    const uint16_t mv2 = bpms::battery_millivolts(600u * 8, 8, other);
    CHECK(mv2 >= 3031 && mv2 <= 3033);  // 600 * 1.1 / 1024 * 127 / 27 = 3.0317 V
}

// ============================================================ cluster board
TEST(cluster_configures_every_chip) {
    Suit s;
    for (int slot = 0; slot < 3; ++slot) {
        auto& bus = s.cluster(2).bus;
        auto& a = bus.chip(slot, bpms::ACCEL);
        CHECK_EQ(a.regs[bpms::ADXL_DATA_FORMAT], 0x0B);  // full resolution, +-16 g
        CHECK_EQ(a.regs[bpms::ADXL_BW_RATE], 0x09);      // 50 Hz
        CHECK_EQ(a.regs[bpms::ADXL_POWER_CTL], 0x08);    // measuring
        CHECK(!a.writes.empty() && a.writes.back().first == bpms::ADXL_POWER_CTL);
        auto& m = bus.chip(slot, bpms::MAG);
        CHECK_EQ(m.regs[bpms::HMC_CRA], 0x18);
        CHECK_EQ(m.regs[bpms::HMC_CRB], 0x20);  // 1090 LSB/G = GainMag
        CHECK_EQ(m.regs[bpms::HMC_MODE], 0x00);  // continuous
        auto& g = bus.chip(slot, bpms::GYRO);
        CHECK_EQ(g.regs[bpms::ITG_DLPF_FS], 0x1B);  // +-2000 deg/s, 42 Hz low-pass
        CHECK_EQ(g.regs[bpms::ITG_SMPLRT_DIV], 0x09);
        CHECK_EQ(g.regs[bpms::ITG_PWR_MGM], 0x01);
    }
}

TEST(cluster_answers_with_stored_reading_then_samples) {
    Suit s;
    auto& c = s.cluster(1);
    CHECK_EQ(c.logic.error_word(), 0);
    CHECK(!c.led.state);
    // Boot took sample 0; a poll returns it and then stores sample 1.
    c.port.rx.push_back(0x00);
    c.port.rx.push_back(0x42);  // a burst counts as one poll; the content is ignored
    c.logic.loop();
    CHECK(c.port.rx.empty());
    CHECK_EQ(c.port.tx.size(), 56u);
    std::vector<uint8_t> reply;
    for (auto& b : c.port.tx) reply.push_back(b.value);
    for (int slot = 0; slot < 3; ++slot)
        for (int ch = 0; ch < 9; ++ch)
            CHECK_EQ(bpms::get_be16s(&reply[18 * slot + 2 * ch]),
                     expected(3 + slot, ch / 3, ch % 3, 0));
    CHECK_EQ(bpms::get_be16(&reply[54]), 0);
    const uint8_t* stored = c.logic.reply();
    CHECK_EQ(bpms::get_be16s(stored + 18 * 2 + 2 * 7), expected(5, 2, 1, 1));  // IMU 5 gy
    const uint32_t idles = c.port.idles;
    c.logic.loop();  // no poll: nothing happens but a sleep until the next byte
    CHECK_EQ(c.port.tx.size(), 56u);
    CHECK_EQ(c.port.idles, idles + 1);
}

// Poll cluster 0 directly and return its error word (the reading stored by that poll's sample).
uint16_t poll_and_sample(sim::ClusterBoard& c) {
    c.port.rx.push_back(0);
    c.logic.loop();
    c.port.tx.clear();
    return c.logic.error_word();
}

TEST(cluster_error_bits_per_fault_kind) {
    Suit s;
    auto& c = s.cluster(0);
    auto fault_at = [](uint32_t bad, sim::Fault kind) {
        return [bad, kind](uint32_t n) { return n == bad ? kind : sim::Fault::NONE; };
    };
    c.bus.chip(0, bpms::ACCEL).fault = fault_at(1, sim::Fault::NACK);
    c.bus.chip(1, bpms::MAG).fault = fault_at(2, sim::Fault::OUT_OF_RANGE);  // -4096 overflow
    c.bus.chip(2, bpms::GYRO).fault = fault_at(3, sim::Fault::ALL_FF);
    c.bus.chip(1, bpms::ACCEL).fault = fault_at(4, sim::Fault::SHORT_READ);
    c.bus.chip(2, bpms::ACCEL).fault = fault_at(5, sim::Fault::OUT_OF_RANGE);  // > 13 bits
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(0, bpms::ACCEL));  // sample 1
    CHECK(c.led.state);
    for (int ch = 0; ch < 3; ++ch) CHECK_EQ(bpms::get_be16s(c.logic.reply() + 2 * ch), 0);
    CHECK_EQ(bpms::get_be16s(c.logic.reply() + 6), expected(0, 1, 0, 1));  // mag unaffected
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(1, bpms::MAG));   // sample 2
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(2, bpms::GYRO));  // sample 3
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(1, bpms::ACCEL));
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(2, bpms::ACCEL));
    CHECK_EQ(poll_and_sample(c), 0);  // every chip recovered
    CHECK(!c.led.state);
    CHECK_EQ(bpms::get_be16s(c.logic.reply()), expected(0, 0, 0, 6));
}

TEST(heel_strike_beyond_2g_is_a_valid_reading) {
    // +-16 g at full resolution: 4 g (1024 counts) and -15.9 g are readings, not failures
    Suit s;
    auto& c = s.cluster(0);
    c.bus.chip(0, bpms::ACCEL).values = [](uint32_t, int16_t v[3]) {
        v[0] = 1024;
        v[1] = -4070;
        v[2] = 256;
    };
    poll_and_sample(c);  // stores a sample with the new values
    CHECK_EQ(poll_and_sample(c), 0);
    // board order swaps chip x and y (Razor AHRS SEN-10724)
    CHECK_EQ(bpms::get_be16s(c.logic.reply()), -4070);
    CHECK_EQ(bpms::get_be16s(c.logic.reply() + 2), 1024);
    CHECK_EQ(bpms::get_be16s(c.logic.reply() + 4), 256);
}

TEST(cluster_reconfigures_a_chip_after_a_failure) {
    Suit s;
    auto& c = s.cluster(3);
    auto& accel = c.bus.chip(1, bpms::ACCEL);
    const size_t writes_after_boot = accel.writes.size();
    poll_and_sample(c);
    CHECK_EQ(accel.writes.size(), writes_after_boot);  // healthy: configured once
    // The stick loses power: the chip comes back in its reset state.
    c.bus.stick_connected[1] = false;
    CHECK_EQ(poll_and_sample(c), 0x038);  // accel, mag and gyro of slot 1
    CHECK(c.led.state);
    accel.regs[bpms::ADXL_POWER_CTL] = 0;
    c.bus.stick_connected[1] = true;
    CHECK_EQ(poll_and_sample(c), 0);
    CHECK_EQ(accel.regs[bpms::ADXL_POWER_CTL], bpms::ADXL_MEASURE);
    CHECK(accel.writes.size() > writes_after_boot);
    CHECK(!c.led.state);
}

TEST(cluster_wrong_chip_identity_is_an_error) {
    Suit s;
    auto& c = s.cluster(0);
    c.bus.chip(2, bpms::MAG).regs[bpms::HMC_ID_A] = 'X';
    c.bus.chip(2, bpms::MAG).present = false;  // make it fail once so it is re-initialised
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(2, bpms::MAG));
    c.bus.chip(2, bpms::MAG).present = true;
    CHECK_EQ(poll_and_sample(c), bpms::error_bit(2, bpms::MAG));  // answers, wrong identity
}

TEST(cluster_without_i2c_multiplexer_flags_everything) {
    Suit s;
    auto& c = s.cluster(4);
    c.bus.mux_present = false;
    CHECK_EQ(poll_and_sample(c), bpms::ERROR_ALL);
    for (int i = 0; i < 54; ++i) CHECK_EQ(c.logic.reply()[i], 0);
    c.bus.mux_present = true;
    CHECK_EQ(poll_and_sample(c), 0);
}

// ============================================================ arbiter commands
TEST(identify_replies_bpms) {
    Suit s;
    s.w.host_send(bpms::CMD_IDENTIFY);
    s.w.run_for(5000);
    CHECK(str(s.w.radio_bytes()) == "BPMS");
    CHECK(!s.w.arbiter->streaming());
}

TEST(battery_reply) {
    Suit s;
    s.w.host_send(bpms::CMD_BATTERY);
    s.w.run_for(5000);
    CHECK(str(s.w.take_radio_bytes()) == "V3.27\n");
    s.w.arbiter_port.battery_adc = 400;  // 400 * 6.6 / 1024 = 2.578 V
    s.w.host_send(bpms::CMD_BATTERY);
    s.w.host_send(bpms::CMD_IDENTIFY);
    s.w.run_for(5000);
    CHECK(str(s.w.take_radio_bytes()) == "V2.58\nBPMS");
}

TEST(a_burst_of_commands_is_answered_in_full) {
    Suit s;
    for (int i = 0; i < 20; ++i) s.w.host_send(bpms::CMD_IDENTIFY);  // more than the queue
    s.w.run_for(20000);
    std::string all = str(s.w.radio_bytes()), want;
    for (int i = 0; i < 20; ++i) want += "BPMS";
    CHECK(all == want);
    CHECK_EQ(s.w.arbiter->stats().dropped_host_bytes, 0);
}

TEST(unknown_command_is_ignored_when_idle) {
    Suit s;
    s.w.host_send(0x7F);
    s.w.run_for(30000);
    CHECK(s.w.radio_bytes().empty());
    CHECK_EQ(s.w.arbiter->stats().unknown_commands, 1);
    CHECK(!s.w.arbiter->streaming());
}

// ============================================================ streaming
TEST(stream_frames_carry_every_cluster_reading) {
    Suit s;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(6));
    CHECK(s.w.arbiter->streaming());
    CHECK(s.w.arbiter_led.state);
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    CHECK(frames.size() >= 6u);
    for (size_t j = 0; j < frames.size(); ++j) CHECK(frame_matches(frames[j], j));
    CHECK_EQ(s.w.misrouted_bytes, 0);
    CHECK_EQ(s.w.cluster_bytes_lost, 0);
    CHECK_EQ(s.w.arbiter_port.rx_overflows, 0);
    CHECK_EQ(s.w.arbiter->stats().cluster_timeouts, 0);
}

TEST(any_byte_stops_the_stream_between_frames_and_is_then_a_command) {
    Suit s;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(3));
    s.w.host_send(bpms::CMD_IDENTIFY);
    s.w.run_for(100000);
    CHECK(!s.w.arbiter->streaming());
    CHECK(!s.w.arbiter_led.state);
    std::vector<uint8_t> bytes = s.w.radio_bytes();
    CHECK(bytes.size() >= 4u && (bytes.size() - 4) % FRAME_BYTES == 0);  // no frame cut short
    CHECK(str(std::vector<uint8_t>(bytes.end() - 4, bytes.end())) == "BPMS");
    std::vector<Frame> frames;
    CHECK(split_frames(std::vector<uint8_t>(bytes.begin(), bytes.end() - 4), frames));
    const uint32_t sent = s.w.arbiter->stats().frames;
    CHECK_EQ(frames.size(), sent);
    s.w.run_for(100000);
    CHECK_EQ(s.w.arbiter->stats().frames, sent);  // stays stopped
    // A stray byte that is not a command stops the stream too, and is then ignored.
    s.w.take_radio_bytes();
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(2));
    s.w.host_send(0x55);
    s.w.run_for(60000);
    CHECK(!s.w.arbiter->streaming());
    CHECK_EQ(s.w.radio_bytes().size() % FRAME_BYTES, 0u);
}

TEST(host_byte_during_cluster_polling_is_held_not_lost) {
    Suit s;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(2));
    // Send while the USART is connected to cluster 3.
    bool sent = false, held = false;
    s.w.arbiter_port.on_select = [&](int channel) {
        if (channel == 3 && !sent) {
            held = s.w.arbiter_port.held;
            s.w.host_send(bpms::CMD_IDENTIFY);
            sent = true;
        }
    };
    s.w.run_for(60000);
    CHECK(sent);
    CHECK(held);
    CHECK(!s.w.arbiter->streaming());
    CHECK_EQ(s.w.host_bytes_lost, 0);
    std::vector<uint8_t> bytes = s.w.radio_bytes();
    CHECK(bytes.size() == 3 * FRAME_BYTES + 4);  // the frame in progress completes
    CHECK(str(std::vector<uint8_t>(bytes.end() - 4, bytes.end())) == "BPMS");
}

TEST(first_frame_after_a_pause_is_stale) {
    Suit s;
    // Values that depend on time (ms) rather than on the sample count.
    for (int k = 0; k < 6; ++k)
        for (int slot = 0; slot < 3; ++slot)
            s.cluster(k).bus.chip(slot, bpms::GYRO).values = [&s](uint32_t, int16_t v[3]) {
                v[0] = v[1] = v[2] = static_cast<int16_t>(s.w.now / 1000);
            };
    s.w.run_for(200000);  // boot sample taken at t = 0, then 200 ms idle
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(3));
    s.w.host_send(0x55);
    s.w.run_for(40000);
    const uint64_t stop_ms = s.w.now / 1000;
    s.w.run_for(500000);  // pause
    s.w.take_radio_bytes();
    s.w.host_send(bpms::CMD_STREAM);
    const uint64_t restart_ms = s.w.now / 1000;
    CHECK(s.run_frames(2));
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    CHECK(frames.size() >= 2u);
    const int16_t first = frames[0].raw[7][6], second = frames[1].raw[7][6];
    CHECK(first < static_cast<int16_t>(stop_ms));  // sampled before the pause
    CHECK(second >= static_cast<int16_t>(restart_ms));  // sampled at the first new poll
    CHECK(second - first >= 500);
}

TEST(silent_or_cut_cluster_gives_zeros_and_all_error_bits) {
    Suit s;
    s.cluster(3).dead = [](uint32_t) { return true; };
    s.cluster(5).port.max_reply_bytes = 30;  // the reply stops after 30 bytes
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(4));
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    CHECK(frames.size() >= 4u);
    for (size_t j = 0; j < frames.size(); ++j) {
        for (int k : {3, 5}) {
            CHECK_EQ(frames[j].error[k], bpms::ERROR_ALL);
            for (int i = 3 * k; i < 3 * k + 3; ++i)
                for (int ch = 0; ch < 9; ++ch) CHECK_EQ(frames[j].raw[i][ch], 0);
        }
        for (int k : {0, 1, 2, 4}) CHECK(cluster_matches(frames[j], k, j));
    }
    CHECK_EQ(s.w.arbiter->stats().cluster_timeouts, 2 * frames.size());
    // Even with two clusters timing out, the period holds.
    const auto& t = s.cluster(0).poll_times;
    for (size_t j = 1; j < t.size(); ++j) CHECK(t[j] - t[j - 1] >= 19990 && t[j] - t[j - 1] <= 20010);
}

TEST(late_reply_of_the_last_cluster_is_not_taken_for_a_host_command) {
    Suit s;
    // Cluster 5 starts answering 2.2 ms after the poll: its reply is still arriving when the
    // arbiter gives up (2.5 ms) and switches back to the radio.
    s.cluster(5).port.reply_delay_us = 2200;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(5));
    CHECK(s.w.arbiter->streaming());
    CHECK_EQ(s.w.arbiter->stats().unknown_commands, 0);
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    CHECK(frames.size() >= 5u);
    for (auto& f : frames) CHECK_EQ(f.error[5], bpms::ERROR_ALL);
    CHECK(s.w.cluster_bytes_lost > 0);  // the rest of its reply went nowhere
}

TEST(all_clusters_silent_still_fits_the_period) {
    Suit s;
    for (int k = 0; k < 6; ++k) s.cluster(k).dead = [](uint32_t) { return true; };
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(10));
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    for (auto& f : frames)
        for (int k = 0; k < 6; ++k) CHECK_EQ(f.error[k], bpms::ERROR_ALL);
    CHECK_EQ(s.w.arbiter->stats().late_starts, 0);
    CHECK_EQ(s.w.arbiter->stats().resyncs, 0);
}

TEST(sensor_error_reaches_the_frame) {
    Suit s;
    s.cluster(4).bus.chip(2, bpms::MAG).fault = [](uint32_t n) {
        return n == 3 ? sim::Fault::OUT_OF_RANGE : sim::Fault::NONE;
    };
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(6));
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    CHECK(frames.size() >= 6u);
    CHECK_EQ(frames[3].error[4], bpms::error_bit(2, bpms::MAG));  // frame 3 returns sample 3
    for (int ch = 3; ch < 6; ++ch) CHECK_EQ(frames[3].raw[14][ch], 0);
    CHECK_EQ(frames[3].raw[14][0], expected(14, 0, 0, 3));
    CHECK(frame_matches(frames[2], 2));
    CHECK(frame_matches(frames[4], 4));
}

// ============================================================ period keeping
// Sampling instants = arrival of the poll at cluster 0.
void check_grid(const std::vector<uint64_t>& t, size_t from, size_t to, int tol) {
    for (size_t j = from; j < to && j < t.size(); ++j) {
        const long long drift = static_cast<long long>(t[j] - t[from]) -
                                static_cast<long long>(j - from) * 20000;
        if (drift < -tol || drift > tol) {
            CHECK_EQ(drift, 0);
            return;
        }
    }
}

TEST(period_is_20ms_without_drift) {
    Suit s;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(200));
    const auto& t = s.cluster(0).poll_times;
    CHECK(t.size() >= 200u);
    check_grid(t, 0, t.size(), 8);
    CHECK_EQ(s.w.arbiter->stats().late_starts, 0);
    // Between frames the arbiter sleeps until a timer tick (1024 us), but only while the
    // deadline is further away than a tick: the grid above holds to 8 us all the same.
    CHECK(s.w.arbiter_port.idles > 200u * 5);
}

TEST(idle_arbiter_wakes_for_a_host_byte) {
    Suit s;
    s.w.run_for(50000);
    const uint32_t idles = s.w.arbiter_port.idles;
    CHECK(idles > 20u);  // asleep, tick after tick
    s.w.host_send(bpms::CMD_IDENTIFY);
    s.w.run_for(100);  // the byte wakes it at once (10 us on the wire), not at the next tick
    CHECK(str(s.w.radio_bytes()) == "BPMS");
}

TEST(period_holds_under_slow_transmission) {
    Suit s;
    s.w.radio_byte_us = 42;  // 340 bytes take 14.3 ms: with the polls, ~18 ms of 20 are busy
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(150));
    const auto& t = s.cluster(0).poll_times;
    check_grid(t, 0, t.size(), 8);
    CHECK_EQ(s.w.arbiter->stats().late_starts, 0);
    CHECK_EQ(s.w.misrouted_bytes, 0);
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    for (size_t j = 0; j < frames.size(); ++j) CHECK(frame_matches(frames[j], j));
}

TEST(one_overrun_frame_does_not_shift_the_grid) {
    Suit s;
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(10));
    s.w.radio_byte_us = 75;  // this frame's 340 bytes take 25.5 ms
    CHECK(s.run_frames(1));
    s.w.radio_byte_us = 10;
    CHECK(s.run_frames(20));
    const auto& t = s.cluster(0).poll_times;
    // Frame 10 was the slow one: frame 11 waits for it to leave, frame 12 is back on the grid.
    CHECK_EQ(s.w.arbiter->stats().late_starts, 1);
    CHECK_EQ(s.w.arbiter->stats().resyncs, 0);
    check_grid(t, 0, 11, 8);
    CHECK(t[11] - t[0] > 11 * 20000 + 1000);
    for (size_t j = 12; j < t.size(); ++j) {
        const long long drift = static_cast<long long>(t[j] - t[0]) -
                                static_cast<long long>(j) * 20000;
        CHECK(drift >= -8 && drift <= 8);
    }
    CHECK_EQ(s.w.misrouted_bytes, 0);
}

TEST(persistent_overrun_degrades_without_bursts) {
    Suit s;
    s.w.radio_byte_us = 80;  // 27 ms per frame: 50 Hz is impossible
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(30));
    const auto& t = s.cluster(0).poll_times;
    for (size_t j = 1; j < t.size(); ++j) CHECK(t[j] - t[j - 1] >= 20000);  // never faster
    CHECK(s.w.arbiter->stats().resyncs > 0);
    s.drain();
    std::vector<Frame> frames;
    CHECK(split_frames(s.w.radio_bytes(), frames));
    for (size_t j = 0; j < frames.size(); ++j) CHECK(frame_matches(frames[j], j));
    CHECK_EQ(s.w.misrouted_bytes, 0);
}

TEST(period_holds_across_micros_wraparound) {
    Suit s(0xFFFFFFFFu - 100000u);  // micros() wraps 100 ms after boot
    s.w.host_send(bpms::CMD_STREAM);
    CHECK(s.run_frames(20));
    const auto& t = s.cluster(0).poll_times;
    check_grid(t, 0, t.size(), 8);
    CHECK_EQ(s.w.arbiter->stats().resyncs, 0);
}

}  // namespace

int main() {
    int passed = 0, failed = 0;
    for (const TestCase& t : registry()) {
        const int before = g_check_failures;
        t.fn();
        if (g_check_failures == before) {
            ++passed;
            std::printf("ok   %s\n", t.name);
        } else {
            ++failed;
            std::printf("FAIL %s\n", t.name);
        }
    }
    std::printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
