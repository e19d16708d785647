#include "sensors.h"

namespace bpms {

const AxisMap AXIS_MAPS[SENSORS_PER_IMU] = {
    {{1, 0, 2}, {1, 1, 1}},  // accel: board x = chip y, board y = chip x
    {{0, 1, 2}, {1, 1, 1}},  // mag: chip axes are the board axes
    {{1, 0, 2}, {1, 1, 1}},  // gyro: board x = chip y, board y = chip x
};

void apply_axis_map(const AxisMap& map, const int16_t chip[AXES], int16_t board[AXES]) {
    for (uint8_t i = 0; i < AXES; ++i) {
        int16_t v = chip[map.src[i]];
        board[i] = map.sign[i] < 0 ? negate_sat(v) : v;
    }
}

bool i2c_write_reg(I2cBus& bus, uint8_t addr, uint8_t reg, uint8_t value) {
    uint8_t msg[2] = {reg, value};
    return bus.write(addr, msg, 2);
}

bool i2c_read_regs(I2cBus& bus, uint8_t addr, uint8_t reg, uint8_t* out, uint8_t n) {
    if (!bus.write(addr, &reg, 1)) return false;
    return bus.read(addr, out, n) == n;
}

bool mux_select(I2cBus& bus, uint8_t slot) {
    uint8_t mask = static_cast<uint8_t>(1u << slot);
    if (!bus.write(MUX_ADDR, &mask, 1)) return false;
    uint8_t back = 0;
    return bus.read(MUX_ADDR, &back, 1) == 1 && back == mask;
}

static bool init_accel(I2cBus& bus) {
    uint8_t id = 0;
    return i2c_read_regs(bus, ADXL345_ADDR, ADXL_DEVID, &id, 1) && id == ADXL_DEVID_VALUE &&
           i2c_write_reg(bus, ADXL345_ADDR, ADXL_POWER_CTL, 0x00) &&  // standby while configuring
           i2c_write_reg(bus, ADXL345_ADDR, ADXL_DATA_FORMAT, ADXL_FULL_RES_16G) &&
           i2c_write_reg(bus, ADXL345_ADDR, ADXL_BW_RATE, ADXL_BW_RATE_50HZ) &&
           i2c_write_reg(bus, ADXL345_ADDR, ADXL_POWER_CTL, ADXL_MEASURE);
}

static bool init_mag(I2cBus& bus) {
    uint8_t id[3] = {0, 0, 0};
    return i2c_read_regs(bus, HMC5883L_ADDR, HMC_ID_A, id, 3) && id[0] == 'H' && id[1] == '4' &&
           id[2] == '3' && i2c_write_reg(bus, HMC5883L_ADDR, HMC_CRA, HMC_CRA_75HZ) &&
           i2c_write_reg(bus, HMC5883L_ADDR, HMC_CRB, HMC_CRB_1090) &&
           i2c_write_reg(bus, HMC5883L_ADDR, HMC_MODE, HMC_CONTINUOUS);
}

static bool init_gyro(I2cBus& bus) {
    uint8_t id = 0;
    return i2c_read_regs(bus, ITG3200_ADDR, ITG_WHO_AM_I, &id, 1) &&
           (id & ITG_WHO_AM_I_MASK) == ITG_WHO_AM_I_VALUE &&
           i2c_write_reg(bus, ITG3200_ADDR, ITG_PWR_MGM, ITG_CLK_PLL_X) &&
           i2c_write_reg(bus, ITG3200_ADDR, ITG_SMPLRT_DIV, ITG_SMPLRT_100HZ) &&
           i2c_write_reg(bus, ITG3200_ADDR, ITG_DLPF_FS, ITG_FS2000_DLPF42);
}

bool sensor_init(I2cBus& bus, Sensor s) {
    switch (s) {
        case ACCEL: return init_accel(bus);
        case MAG: return init_mag(bus);
        case GYRO: return init_gyro(bus);
    }
    return false;
}

static bool all_ff(const uint8_t* b, uint8_t n) {
    for (uint8_t i = 0; i < n; ++i)
        if (b[i] != 0xFF) return false;
    return true;
}

static bool in_range(const int16_t v[AXES], int16_t lo, int16_t hi) {
    for (uint8_t i = 0; i < AXES; ++i)
        if (v[i] < lo || v[i] > hi) return false;
    return true;
}

bool sensor_read(I2cBus& bus, Sensor s, int16_t chip[AXES]) {
    uint8_t b[6];
    switch (s) {
        case ACCEL:
            if (!i2c_read_regs(bus, ADXL345_ADDR, ADXL_DATAX0, b, 6) || all_ff(b, 6)) return false;
            chip[0] = get_le16s(b);
            chip[1] = get_le16s(b + 2);
            chip[2] = get_le16s(b + 4);
            return in_range(chip, ADXL_MIN, ADXL_MAX);
        case MAG:
            if (!i2c_read_regs(bus, HMC5883L_ADDR, HMC_DATA, b, 6) || all_ff(b, 6)) return false;
            chip[0] = get_be16s(b);
            chip[2] = get_be16s(b + 2);
            chip[1] = get_be16s(b + 4);
            return in_range(chip, -2048, 2047);  // 12-bit; -4096 flags an overflow
        case GYRO:
            if (!i2c_read_regs(bus, ITG3200_ADDR, ITG_GYRO_XOUT_H, b, 6) || all_ff(b, 6))
                return false;
            chip[0] = get_be16s(b);
            chip[1] = get_be16s(b + 2);
            chip[2] = get_be16s(b + 4);
            return true;
    }
    return false;
}

}  // namespace bpms
