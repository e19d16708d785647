// Each cluster's I2C bus: a TCA9548A multiplexer at 0x70 and, on its channels 0..2, one
// SEN-10724 stick each (ADXL345 at 0x53, HMC5883L at 0x1E, ITG-3200 at 0x68), as register
// models of the three data sheets: identity registers, configuration registers that matter
// for the output (a chip left in its power-on configuration reads wrong, as a real one would),
// auto-incrementing register pointers, and data registers filled from the motion table.
//
// The table holds chip-axis counts at the settings the firmware is meant to make: 256 LSB/g
// (ADXL345 full resolution), 1090 LSB/G (HMC5883L gain 1), 14.375 LSB per deg/s (ITG-3200,
// FS_SEL 3). A chip that is switched off does not acknowledge its address; switched on again
// it starts from its power-on registers.
#include <string.h>

#include "suit_host.h"

#define MUX_ADDR 0x70
static const uint8_t chip_addr[3] = {0x53, 0x1E, 0x68};

typedef struct {
    int kind;
    int imu;
    int powered;
    uint8_t regs[64];
    uint8_t ptr;
    uint8_t out[6];   // data registers latched at the start of a read
    int16_t held[3];  // HMC5883L: the last measurement (single or idle mode)
} chip_t;

typedef struct {
    board_t* board;
    avr_irq_t* twi_input;
    uint8_t mux_ctrl;
    int target;  // -1 none, 0 the multiplexer, 1 + 3 * slot + sensor a chip
    uint8_t addr8;
    int bytes_written;  // in this transaction
    int64_t sample;     // motion sample the chips show, -1: none yet (zeros)
    uint64_t i2c_bytes, nacks;
    chip_t chips[3][3];
} cluster_bus_t;

static cluster_bus_t buses[N_CLUSTERS];
static const motion_table_t* motion;

static void chip_reset(chip_t* c) {
    memset(c->regs, 0, sizeof c->regs);
    memset(c->held, 0, sizeof c->held);
    c->ptr = 0;
    switch (c->kind) {
        case SENSOR_ACCEL:
            c->regs[0x00] = 0xE5;  // DEVID
            c->regs[0x2C] = 0x0A;  // BW_RATE 100 Hz; POWER_CTL 0 = standby; DATA_FORMAT 0
            break;
        case SENSOR_MAG:
            c->regs[0x00] = 0x10;  // CRA 15 Hz
            c->regs[0x01] = 0x20;  // CRB gain 1090 LSB/G
            c->regs[0x02] = 0x01;  // MODE single measurement (nothing measured yet)
            c->regs[0x0A] = 'H', c->regs[0x0B] = '4', c->regs[0x0C] = '3';
            break;
        case SENSOR_GYRO:
            c->regs[0x00] = 0x68;  // WHO_AM_I; DLPF_FS 0 (FS_SEL 0 is not a valid range)
            break;
    }
}

static int16_t table_value(const cluster_bus_t* bus, const chip_t* c, int axis) {
    if (bus->sample < 0 || !motion || motion->n_samples == 0) return 0;
    const uint64_t k = (uint64_t)bus->sample % motion->n_samples;
    return motion->values[((k * 18 + (uint64_t)c->imu) * 3 + (uint64_t)c->kind) * 3 + (uint64_t)axis];
}

static int32_t scaled(int32_t v, int32_t num, int32_t den) {  // v * num / den, rounded
    const int64_t p = (int64_t)v * num;
    return (int32_t)(p >= 0 ? (p + den / 2) / den : -((-p + den / 2) / den));
}

static int32_t clamp(int32_t v, int32_t lo, int32_t hi) { return v < lo ? lo : v > hi ? hi : v; }

static int16_t accel_out(const cluster_bus_t* bus, const chip_t* c, int axis) {
    if (!(c->regs[0x2D] & 0x08)) return 0;  // standby: no measurement
    const uint8_t fmt = c->regs[0x31];
    const int32_t range_g = 2 << (fmt & 3);
    const int32_t v = table_value(bus, c, axis);
    if (fmt & 0x08) return (int16_t)clamp(v, -range_g * 256, range_g * 256 - 1);  // 256 LSB/g
    return (int16_t)clamp(scaled(v, 2, range_g), -512, 511);  // 10 bits over +-range
}

static int16_t mag_measure(const cluster_bus_t* bus, const chip_t* c, int axis) {
    static const int32_t gain[8] = {1370, 1090, 820, 660, 440, 390, 330, 230};
    const int32_t v = scaled(table_value(bus, c, axis), gain[c->regs[0x01] >> 5], 1090);
    return (int16_t)(v < -2048 || v > 2047 ? -4096 : v);  // the chip's overflow value
}

static int16_t gyro_out(const cluster_bus_t* bus, const chip_t* c, int axis) {
    if (((c->regs[0x16] >> 3) & 3) != 3 || (c->regs[0x3E] & 0x40)) return 0;  // not set up / asleep
    return table_value(bus, c, axis);
}

// Latch the six data registers as a burst read would see them.
static void latch(cluster_bus_t* bus, chip_t* c) {
    int16_t v[3];
    switch (c->kind) {
        case SENSOR_ACCEL:
            for (int a = 0; a < 3; ++a) v[a] = accel_out(bus, c, a);
            for (int a = 0; a < 3; ++a) {  // X0 X1 Y0 Y1 Z0 Z1, little-endian
                c->out[2 * a] = (uint8_t)(v[a] & 0xFF);
                c->out[2 * a + 1] = (uint8_t)((uint16_t)v[a] >> 8);
            }
            break;
        case SENSOR_MAG: {
            if ((c->regs[0x02] & 3) == 0)  // continuous: a fresh measurement
                for (int a = 0; a < 3; ++a) c->held[a] = mag_measure(bus, c, a);
            static const int order[3] = {0, 2, 1};  // X, Z, Y, big-endian
            for (int i = 0; i < 3; ++i) {
                c->out[2 * i] = (uint8_t)((uint16_t)c->held[order[i]] >> 8);
                c->out[2 * i + 1] = (uint8_t)(c->held[order[i]] & 0xFF);
            }
            break;
        }
        case SENSOR_GYRO:
            for (int a = 0; a < 3; ++a) v[a] = gyro_out(bus, c, a);
            for (int a = 0; a < 3; ++a) {  // X, Y, Z, big-endian
                c->out[2 * a] = (uint8_t)((uint16_t)v[a] >> 8);
                c->out[2 * a + 1] = (uint8_t)(v[a] & 0xFF);
            }
            break;
    }
}

static int data_index(const chip_t* c, uint8_t reg) {
    static const uint8_t first[3] = {0x32, 0x03, 0x1D};
    const int i = (int)reg - first[c->kind];
    return i >= 0 && i < 6 ? i : -1;
}

static uint8_t chip_read(chip_t* c) {
    const int i = data_index(c, c->ptr);
    const uint8_t v = i >= 0 ? c->out[i] : c->regs[c->ptr & 63];
    if (c->kind == SENSOR_MAG)  // the pointer wraps 12 -> 0, and back to 3 after the data
        c->ptr = c->ptr == 0x08 ? 0x03 : c->ptr >= 0x0C ? 0 : (uint8_t)(c->ptr + 1);
    else
        c->ptr = (uint8_t)((c->ptr + 1) & 63);
    return v;
}

static void chip_write(cluster_bus_t* bus, chip_t* c, uint8_t v, int first) {
    if (first) {
        c->ptr = v;
        return;
    }
    const uint8_t reg = c->ptr & 63;
    const int read_only = (c->kind == SENSOR_ACCEL && reg == 0x00) ||
                          (c->kind == SENSOR_MAG && reg >= 0x03) ||
                          (c->kind == SENSOR_GYRO && (reg == 0x00 ? 0 : reg >= 0x1B && reg <= 0x22));
    if (!read_only) c->regs[reg] = v;
    if (c->kind == SENSOR_MAG && reg == 0x02 && (v & 3) == 1) {  // single measurement, then idle
        for (int a = 0; a < 3; ++a) c->held[a] = mag_measure(bus, c, a);
        c->regs[0x02] = (uint8_t)((v & ~3) | 3);
    }
    c->ptr = (uint8_t)((c->ptr + 1) & 63);
}

static void reply(cluster_bus_t* bus, uint8_t msg, uint8_t data) {
    avr_raise_irq(bus->twi_input, avr_twi_irq_msg(msg, bus->addr8, data));
}

static int find_target(const cluster_bus_t* bus, uint8_t addr7) {
    if (addr7 == MUX_ADDR) return 0;
    for (int slot = 0; slot < 3; ++slot) {
        if (!(bus->mux_ctrl & (1u << slot))) continue;  // channels 3..7 carry nothing
        for (int s = 0; s < 3; ++s)
            if (chip_addr[s] == addr7 && bus->chips[slot][s].powered) return 1 + 3 * slot + s;
    }
    return -1;
}

static void twi_message(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    cluster_bus_t* bus = param;
    avr_twi_msg_irq_t m;
    m.u.v = value;
    const uint8_t msg = m.u.twi.msg;
    if (msg & TWI_COND_STOP) bus->target = -1;
    if (msg & TWI_COND_START) {
        ++bus->i2c_bytes;  // the address byte
        bus->addr8 = m.u.twi.addr;
        bus->target = find_target(bus, (uint8_t)(bus->addr8 >> 1));
        bus->bytes_written = 0;
        if (bus->target < 0) {
            ++bus->nacks;
            return;
        }
        if (bus->target > 0 && (bus->addr8 & 1)) {
            const int t = bus->target - 1;
            latch(bus, &bus->chips[t / 3][t % 3]);
        }
        reply(bus, TWI_COND_ACK, 1);
        return;
    }
    if (bus->target < 0) return;
    chip_t* c = bus->target > 0 ? &bus->chips[(bus->target - 1) / 3][(bus->target - 1) % 3] : NULL;
    if (msg & TWI_COND_WRITE) {
        ++bus->i2c_bytes;
        if (c)
            chip_write(bus, c, m.u.twi.data, bus->bytes_written == 0);
        else
            bus->mux_ctrl = m.u.twi.data;
        ++bus->bytes_written;
        reply(bus, TWI_COND_ACK, 1);
    } else if (msg & TWI_COND_READ) {
        ++bus->i2c_bytes;
        reply(bus, TWI_COND_READ, c ? chip_read(c) : bus->mux_ctrl);
    }
}

void chips_init(board_t* clusters[N_CLUSTERS], const motion_table_t* table) {
    motion = table;
    for (int k = 0; k < N_CLUSTERS; ++k) {
        cluster_bus_t* bus = &buses[k];
        memset(bus, 0, sizeof *bus);
        bus->board = clusters[k];
        bus->target = -1;
        bus->sample = -1;
        avr_t* avr = clusters[k]->avr;
        bus->twi_input = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
        avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT),
                                twi_message, bus);
        for (int slot = 0; slot < 3; ++slot)
            for (int s = 0; s < 3; ++s) {
                chip_t* c = &bus->chips[slot][s];
                c->kind = s;
                c->imu = 3 * k + slot;
                c->powered = 1;
                chip_reset(c);
            }
    }
}

void chips_poll(int cluster, uint64_t poll) { buses[cluster].sample = (int64_t)poll - 1; }

void chips_power(int imu, int sensor, int on) {
    chip_t* c = &buses[imu / 3].chips[imu % 3][sensor];
    if (on && !c->powered) chip_reset(c);  // back from a power loss: power-on registers
    c->powered = on;
}

int chips_powered(int imu, int sensor) { return buses[imu / 3].chips[imu % 3][sensor].powered; }

uint64_t chips_i2c_bytes(int cluster) { return buses[cluster].i2c_bytes; }

uint64_t chips_nacks(int cluster) { return buses[cluster].nacks; }
