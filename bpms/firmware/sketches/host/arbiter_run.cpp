// Simulated suit run: the arbiter logic and six cluster boards on fake hardware with scripted
// sensor values (sim::scripted_value). The host sends 0x02, 0x01, 0x00, lets K frames stream,
// then stops the stream; every byte the RN-41 received is written to the output file:
//     "BPMS" "V3.27\n" K * 340-byte frames
// With --faults, a fixed set of sensor faults and silent-cluster polls is injected and
// described in a JSON file (--scenario) so that a test can predict the frames independently.
//
// usage: arbiter_run --frames K --out FILE [--faults --scenario FILE.json]
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "host/fake_hardware.h"

namespace {

struct SensorFault {
    int imu, sensor;
    uint32_t sample;
    sim::Fault kind;
    const char* name;
};

const SensorFault FAULTS[] = {
    {4, 0, 3, sim::Fault::NACK, "nack"},
    {4, 0, 4, sim::Fault::NACK, "nack"},
    {13, 1, 2, sim::Fault::OUT_OF_RANGE, "out_of_range"},
    {8, 2, 6, sim::Fault::ALL_FF, "all_ff"},
    {17, 0, 5, sim::Fault::SHORT_READ, "short_read"},
    {9, 2, 0, sim::Fault::NACK, "nack"},  // the boot sample, returned by frame 0
};

struct DeadPolls {
    int cluster;
    std::vector<uint32_t> polls;
};
const DeadPolls DEAD[] = {{5, {8, 9}}, {0, {2}}};

int usage() {
    std::fprintf(stderr, "usage: arbiter_run --frames K --out FILE [--faults --scenario FILE]\n");
    return 2;
}

void install_faults(sim::World& w) {
    for (const SensorFault& f : FAULTS) {
        auto& chip = w.clusters[f.imu / 3]->bus.chip(f.imu % 3, static_cast<bpms::Sensor>(f.sensor));
        auto previous = chip.fault;
        const uint32_t sample = f.sample;
        const sim::Fault kind = f.kind;
        chip.fault = [previous, sample, kind](uint32_t n) {
            if (n == sample) return kind;
            return previous ? previous(n) : sim::Fault::NONE;
        };
    }
    for (const DeadPolls& d : DEAD) {
        std::set<uint32_t> polls(d.polls.begin(), d.polls.end());
        w.clusters[d.cluster]->dead = [polls](uint32_t p) { return polls.count(p) > 0; };
    }
}

bool write_scenario(const char* path) {
    FILE* f = std::fopen(path, "w");
    if (!f) return false;
    std::fprintf(f, "{\n  \"sensor_faults\": [\n");
    const size_t n = sizeof FAULTS / sizeof FAULTS[0];
    for (size_t i = 0; i < n; ++i)
        std::fprintf(f, "    {\"imu\": %d, \"sensor\": %d, \"sample\": %u, \"kind\": \"%s\"}%s\n",
                     FAULTS[i].imu, FAULTS[i].sensor, FAULTS[i].sample, FAULTS[i].name,
                     i + 1 < n ? "," : "");
    std::fprintf(f, "  ],\n  \"silent_polls\": [\n");
    const size_t m = sizeof DEAD / sizeof DEAD[0];
    for (size_t i = 0; i < m; ++i) {
        std::fprintf(f, "    {\"cluster\": %d, \"polls\": [", DEAD[i].cluster);
        for (size_t j = 0; j < DEAD[i].polls.size(); ++j)
            std::fprintf(f, "%s%u", j ? ", " : "", DEAD[i].polls[j]);
        std::fprintf(f, "]}%s\n", i + 1 < m ? "," : "");
    }
    std::fprintf(f, "  ]\n}\n");
    return std::fclose(f) == 0;
}

}  // namespace

int main(int argc, char** argv) {
    long frames = -1;
    const char* out = nullptr;
    const char* scenario = nullptr;
    bool faults = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) frames = std::atol(argv[++i]);
        else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!std::strcmp(argv[i], "--scenario") && i + 1 < argc) scenario = argv[++i];
        else if (!std::strcmp(argv[i], "--faults")) faults = true;
        else return usage();
    }
    if (frames < 1 || frames > 100000 || !out) return usage();

    sim::World w;
    sim::script_all(w);
    if (faults) install_faults(w);
    w.boot();
    w.run_for(10000);
    w.host_send(bpms::CMD_IDENTIFY);
    w.run_for(5000);
    w.host_send(bpms::CMD_BATTERY);
    w.run_for(5000);
    w.host_send(bpms::CMD_STREAM);
    const uint32_t k = static_cast<uint32_t>(frames);
    if (!w.run_until([&] { return w.arbiter->stats().frames >= k; }, 30000ull * k + 1000000)) {
        std::fprintf(stderr, "arbiter_run: only %u frames were sent\n", w.arbiter->stats().frames);
        return 1;
    }
    w.host_send(0x55);  // stop: any byte that is not a command
    w.run_for(100000);
    if (w.arbiter->streaming() || w.arbiter->stats().frames != k) {
        std::fprintf(stderr, "arbiter_run: the stream did not stop after %u frames\n", k);
        return 1;
    }
    const std::vector<uint8_t> bytes = w.radio_bytes();
    FILE* f = std::fopen(out, "wb");
    if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() || std::fclose(f)) {
        std::fprintf(stderr, "arbiter_run: cannot write %s\n", out);
        return 1;
    }
    if (scenario && !write_scenario(scenario)) {
        std::fprintf(stderr, "arbiter_run: cannot write %s\n", scenario);
        return 1;
    }
    const bpms::ArbiterStats& st = w.arbiter->stats();
    std::printf("frames %u bytes %zu cluster_timeouts %u late_starts %u resyncs %u "
                "misrouted %llu host_bytes_lost %llu\n",
                st.frames, bytes.size(), st.cluster_timeouts, st.late_starts, st.resyncs,
                static_cast<unsigned long long>(w.misrouted_bytes),
                static_cast<unsigned long long>(w.host_bytes_lost));
    return 0;
}
