#include "fake_hardware.h"

#include <algorithm>

namespace sim {

// ---------------------------------------------------------------- clock
uint32_t SimClock::micros() {
    world_.advance(tick_us);
    return world_.clock_start + static_cast<uint32_t>(world_.now);
}

void SimClock::delay_micros(uint16_t us) { world_.advance(us); }

// ---------------------------------------------------------------- chips
FakeChip::FakeChip(uint8_t a, bpms::Sensor k) : addr(a), kind(k) {
    switch (kind) {
        case bpms::ACCEL: regs[bpms::ADXL_DEVID] = bpms::ADXL_DEVID_VALUE; break;
        case bpms::MAG:
            regs[bpms::HMC_ID_A] = 'H';
            regs[bpms::HMC_ID_A + 1] = '4';
            regs[bpms::HMC_ID_A + 2] = '3';
            break;
        case bpms::GYRO: regs[bpms::ITG_WHO_AM_I] = 0x68; break;
    }
}

uint8_t FakeChip::data_reg() const {
    switch (kind) {
        case bpms::ACCEL: return bpms::ADXL_DATAX0;
        case bpms::MAG: return bpms::HMC_DATA;
        case bpms::GYRO: return bpms::ITG_GYRO_XOUT_H;
    }
    return 0;
}

static void be(uint8_t* p, int16_t v) { bpms::put_be16s(p, v); }

void FakeChip::load_sample() {
    int16_t v[3] = {0, 0, 0};
    if (values) values(samples, v);
    if (pending_ == Fault::OUT_OF_RANGE) {
        if (kind == bpms::ACCEL) v[0] = 5000;         // beyond 13 bits at full resolution
        else if (kind == bpms::MAG) v[1] = -4096;     // the HMC5883L's overflow value
        else pending_ = Fault::ALL_FF;                // the gyro has no invalid range
    }
    uint8_t* d = regs + data_reg();
    switch (kind) {
        case bpms::ACCEL:  // little-endian x, y, z
            for (int a = 0; a < 3; ++a) {
                d[2 * a] = static_cast<uint8_t>(static_cast<uint16_t>(v[a]) & 0xFF);
                d[2 * a + 1] = static_cast<uint8_t>(static_cast<uint16_t>(v[a]) >> 8);
            }
            break;
        case bpms::MAG:  // big-endian x, z, y
            be(d, v[0]);
            be(d + 2, v[2]);
            be(d + 4, v[1]);
            break;
        case bpms::GYRO:  // big-endian x, y, z
            be(d, v[0]);
            be(d + 2, v[1]);
            be(d + 4, v[2]);
            break;
    }
}

bool FakeChip::write(const uint8_t* data, uint8_t n) {
    if (!present || n == 0) return false;
    ptr_ = data[0];
    if (n == 1) {
        pending_ = Fault::NONE;
        if (ptr_ == data_reg()) {  // the start of a data read: a new sample
            pending_ = fault ? fault(samples) : Fault::NONE;
            if (pending_ == Fault::NACK) {
                ++samples;
                pending_ = Fault::NONE;
                return false;
            }
            load_sample();
            ++samples;
        }
        return true;
    }
    for (uint8_t i = 1; i < n; ++i) {
        writes.push_back({ptr_, data[i]});
        regs[ptr_++] = data[i];
    }
    return true;
}

uint8_t FakeChip::read(uint8_t* data, uint8_t n) {
    if (!present) return 0;
    Fault f = pending_;
    pending_ = Fault::NONE;
    if (f == Fault::SHORT_READ) n = static_cast<uint8_t>(n / 2);
    for (uint8_t i = 0; i < n; ++i) data[i] = f == Fault::ALL_FF ? 0xFF : regs[ptr_++];
    return n;
}

// ---------------------------------------------------------------- I2C bus with the mux
FakeI2cBus::FakeI2cBus() {
    for (int slot = 0; slot < 3; ++slot) {
        chips_.emplace_back(new FakeChip(bpms::ADXL345_ADDR, bpms::ACCEL));
        chips_.emplace_back(new FakeChip(bpms::HMC5883L_ADDR, bpms::MAG));
        chips_.emplace_back(new FakeChip(bpms::ITG3200_ADDR, bpms::GYRO));
    }
}

FakeChip* FakeI2cBus::route(uint8_t addr) {
    FakeChip* found = nullptr;
    for (int slot = 0; slot < 3; ++slot) {
        if (!(mux_mask & (1 << slot)) || !stick_connected[slot]) continue;
        for (int s = 0; s < 3; ++s) {
            FakeChip& c = *chips_[slot * 3 + s];
            if (c.addr != addr) continue;
            if (found) return nullptr;  // two sticks answering at once: garbage, call it a NACK
            found = &c;
        }
    }
    return found;
}

bool FakeI2cBus::write(uint8_t addr, const uint8_t* data, uint8_t n) {
    if (addr == bpms::MUX_ADDR) {
        if (!mux_present || n != 1) return false;
        mux_mask = data[0];
        return true;
    }
    FakeChip* c = route(addr);
    return c && c->write(data, n);
}

uint8_t FakeI2cBus::read(uint8_t addr, uint8_t* data, uint8_t n) {
    if (addr == bpms::MUX_ADDR) {
        if (!mux_present || n == 0) return 0;
        data[0] = mux_mask;
        return 1;
    }
    FakeChip* c = route(addr);
    return c ? c->read(data, n) : 0;
}

// ---------------------------------------------------------------- serial wires
int ClusterPort::read() {
    if (rx.empty()) return -1;
    int v = rx.front();
    rx.pop_front();
    return v;
}

void ClusterPort::write(const uint8_t* data, uint16_t n) {
    uint64_t t = world_.now + reply_delay_us;
    if (!tx.empty()) t = std::max(t, tx.back().time);
    if (max_reply_bytes >= 0 && n > max_reply_bytes) n = static_cast<uint16_t>(max_reply_bytes);
    for (uint16_t i = 0; i < n; ++i) {
        t += world_.cluster_byte_us;
        tx.push_back({t, data[i], index_});
    }
}

void ClusterPort::flush() {
    if (!tx.empty() && tx.back().time > world_.now) world_.advance(tx.back().time - world_.now);
}

int ArbiterPort::available() {
    world_.process();
    return static_cast<int>(rx.size());
}

int ArbiterPort::read() {
    world_.process();
    if (rx.empty()) return -1;
    int v = rx.front();
    rx.pop_front();
    return v;
}

void ArbiterPort::write(const uint8_t* data, uint16_t n) {
    for (uint16_t i = 0; i < n; ++i) {
        world_.process();
        if (tx.size() >= TX_BUFFER) world_.advance(tx.front().time - world_.now);  // blocks
        uint64_t t = tx.empty() ? world_.now : std::max(world_.now, tx.back().time);
        t += channel == RADIO ? world_.radio_byte_us : world_.cluster_byte_us;
        tx.push_back({t, data[i], channel});
    }
}

void ArbiterPort::flush() {
    world_.process();
    if (!tx.empty()) world_.advance(tx.back().time - world_.now);
}

void ArbiterPort::idle() {
    ++idles;
    world_.process();
    const uint64_t tick = (world_.now / TICK_US + 1) * TICK_US;
    while (rx.empty() && world_.now < tick) world_.advance(1);
}

void ArbiterPort::select_channel(uint8_t c) {
    world_.process();
    channel = c;
    if (on_select) on_select(c);
}

void ArbiterPort::hold_radio(bool hold) {
    world_.process();
    held = hold;
}

// ---------------------------------------------------------------- the suit
ClusterBoard::ClusterBoard(World& world, int index)
    : port(world, index), logic(bus, port, led) {}

World::World(uint32_t start)
    : clock_start(start), clock(*this), arbiter_port(*this) {
    for (int k = 0; k < bpms::N_CLUSTERS; ++k) clusters.emplace_back(new ClusterBoard(*this, k));
    arbiter.reset(new bpms::ArbiterLogic(arbiter_port, arbiter_port, clock, arbiter_led));
}

void World::boot() {
    for (auto& c : clusters) c->logic.begin();
    arbiter->begin();
}

void World::advance(uint64_t us) {
    const uint64_t target = now + us;
    while (now < target) {
        now = std::min(now + 5, target);  // 5 us steps: half a byte time at 1 Mbaud
        process();
    }
}

void World::deliver_arbiter_byte(const TimedByte& b) {
    const int ch = arbiter_port.channel;
    if (ch != b.channel) ++misrouted_bytes;
    if (ch == bpms::ArbiterBoard::RADIO) {
        radio_in.push_back({b.time, b.value});
        return;
    }
    ClusterBoard& c = *clusters[ch];
    const uint32_t poll = c.polls_seen++;
    if (c.dead && c.dead(poll)) return;
    c.poll_times.push_back(b.time);
    c.port.rx.push_back(b.value);
}

void World::process() {
    auto& atx = arbiter_port.tx;
    while (!atx.empty() && atx.front().time <= now) {
        TimedByte b = atx.front();
        atx.pop_front();
        deliver_arbiter_byte(b);
    }
    for (auto& c : clusters)
        if (!c->port.rx.empty()) c->logic.loop();
    for (int k = 0; k < bpms::N_CLUSTERS; ++k) {
        auto& ctx = clusters[k]->port.tx;
        while (!ctx.empty() && ctx.front().time <= now) {
            uint8_t v = ctx.front().value;
            ctx.pop_front();
            if (arbiter_port.channel != k) {
                ++cluster_bytes_lost;
            } else if (arbiter_port.rx.size() >= ArbiterPort::RX_BUFFER) {
                ++arbiter_port.rx_overflows;
            } else {
                arbiter_port.rx.push_back(v);
            }
        }
    }
    // RN-41 -> arbiter: a byte starts only while CTS allows; once started it completes.
    if (host_inflight_time && *host_inflight_time <= now) {
        if (arbiter_port.channel != bpms::ArbiterBoard::RADIO) ++host_bytes_lost;
        else if (arbiter_port.rx.size() >= ArbiterPort::RX_BUFFER) ++arbiter_port.rx_overflows;
        else arbiter_port.rx.push_back(host_inflight_value);
        host_inflight_time.reset();
    }
    if (!host_inflight_time && !arbiter_port.held && !host_pending.empty()) {
        host_inflight_value = host_pending.front();
        host_pending.pop_front();
        host_inflight_time = now + host_byte_us;
    }
}

void World::host_send(uint8_t byte) {
    host_pending.push_back(byte);
    process();
}

bool World::run_until(const std::function<bool()>& done, uint64_t max_us) {
    const uint64_t end = now + max_us;
    while (now < end) {
        arbiter->loop();
        if (done()) return true;
        advance(2);  // the loop's own CPU time
    }
    return done();
}

void World::run_for(uint64_t us) {
    run_until([] { return false; }, us);
}

std::vector<uint8_t> World::radio_bytes() const {
    std::vector<uint8_t> out;
    out.reserve(radio_in.size());
    for (const auto& b : radio_in) out.push_back(b.value);
    return out;
}

std::vector<uint8_t> World::take_radio_bytes() {
    std::vector<uint8_t> out = radio_bytes();
    radio_in.clear();
    return out;
}

// ---------------------------------------------------------------- scripted values
int16_t scripted_value(int imu, int sensor, int axis, uint32_t sample) {
    static const uint32_t span[3] = {1000, 4000, 60000};  // accel +-500, mag +-2000, gyro +-30000
    const uint32_t mix = sample * 7919u + static_cast<uint32_t>(imu) * 104729u +
                         static_cast<uint32_t>(sensor) * 1299709u +
                         static_cast<uint32_t>(axis) * 15485863u;
    return static_cast<int16_t>(static_cast<int32_t>(mix % span[sensor]) -
                                static_cast<int32_t>(span[sensor] / 2));
}

void script_all(World& world) {
    for (int k = 0; k < bpms::N_CLUSTERS; ++k)
        for (int slot = 0; slot < 3; ++slot)
            for (int s = 0; s < 3; ++s) {
                const int imu = 3 * k + slot;
                world.clusters[k]->bus.chip(slot, static_cast<bpms::Sensor>(s)).values =
                    [imu, s](uint32_t n, int16_t v[3]) {
                        for (int a = 0; a < 3; ++a) v[a] = scripted_value(imu, s, a, n);
                    };
            }
}

}  // namespace sim
