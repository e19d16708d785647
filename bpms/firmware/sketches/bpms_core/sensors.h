// The SEN-10724 sensor stick's three chips behind a TCA9548A/PCA9548A I2C multiplexer:
// register constants, configuration, reading and validation, and the chip -> board axis map.
#ifndef BPMS_SENSORS_H
#define BPMS_SENSORS_H

#include <stdint.h>

#include "hal.h"
#include "protocol.h"

namespace bpms {

// I2C addresses (7-bit). The multiplexer's A0..A2 are tied low; stick k sits on channel k.
const uint8_t MUX_ADDR = 0x70;
const uint8_t ADXL345_ADDR = 0x53;   // SDO/ALT low on the stick
const uint8_t HMC5883L_ADDR = 0x1E;
const uint8_t ITG3200_ADDR = 0x68;   // AD0 low on the stick

// ADXL345 registers and settings: full resolution, +-16 g (3.9 mg/LSB = 256 LSB/g at every
// range in full resolution, 13-bit), 50 Hz ODR. The original firmware used +-2 g (10-bit), which
// clips heel strikes (2-5 g on the foot); the calibration units do not change.
const uint8_t ADXL_DEVID = 0x00, ADXL_DEVID_VALUE = 0xE5;
const uint8_t ADXL_BW_RATE = 0x2C, ADXL_BW_RATE_50HZ = 0x09;
const uint8_t ADXL_POWER_CTL = 0x2D, ADXL_MEASURE = 0x08;
const uint8_t ADXL_DATA_FORMAT = 0x31, ADXL_FULL_RES_16G = 0x0B;  // FULL_RES | range 11
const int16_t ADXL_MIN = -4096, ADXL_MAX = 4095;  // 13-bit at full resolution, +-16 g
const uint8_t ADXL_DATAX0 = 0x32;  // X0 X1 Y0 Y1 Z0 Z1, little-endian

// HMC5883L registers and settings: 1 sample averaged, 75 Hz, gain 1090 LSB/G (0.917 mG/LSB,
// the suite's GainMag), continuous measurement.
const uint8_t HMC_CRA = 0x00, HMC_CRA_75HZ = 0x18;
const uint8_t HMC_CRB = 0x01, HMC_CRB_1090 = 0x20;
const uint8_t HMC_MODE = 0x02, HMC_CONTINUOUS = 0x00;
const uint8_t HMC_DATA = 0x03;  // X MSB, X LSB, Z MSB, Z LSB, Y MSB, Y LSB (note X Z Y)
const uint8_t HMC_ID_A = 0x0A;  // "H43"
const int16_t HMC_OVERFLOW = -4096;

// ITG-3200 registers and settings: +-2000 deg/s (FS_SEL=3), 42 Hz low-pass, 1 kHz internal
// rate / 10 = 100 Hz samples, PLL with the X gyro as clock.
const uint8_t ITG_WHO_AM_I = 0x00, ITG_WHO_AM_I_MASK = 0x7E, ITG_WHO_AM_I_VALUE = 0x68;
const uint8_t ITG_SMPLRT_DIV = 0x15, ITG_SMPLRT_100HZ = 0x09;
const uint8_t ITG_DLPF_FS = 0x16, ITG_FS2000_DLPF42 = 0x1B;
const uint8_t ITG_PWR_MGM = 0x3E, ITG_CLK_PLL_X = 0x01;
const uint8_t ITG_GYRO_XOUT_H = 0x1D;  // X H, X L, Y H, Y L, Z H, Z L, big-endian

// Board axis i = sign[i] * chip axis src[i]. "Board order" is the Razor AHRS convention for the
// SEN-10724 (X along the HMC5883L's x): the ADXL345 and ITG-3200 have x and y swapped with
// respect to it. Signs stay +1 here: docs/units.md puts the sign changes on the host.
struct AxisMap {
    uint8_t src[AXES];
    int8_t sign[AXES];
};
extern const AxisMap AXIS_MAPS[SENSORS_PER_IMU];  // indexed by Sensor

void apply_axis_map(const AxisMap& map, const int16_t chip[AXES], int16_t board[AXES]);

bool i2c_write_reg(I2cBus& bus, uint8_t addr, uint8_t reg, uint8_t value);
bool i2c_read_regs(I2cBus& bus, uint8_t addr, uint8_t reg, uint8_t* out, uint8_t n);

// Connect only channel `slot` of the multiplexer; reads the control register back to check.
bool mux_select(I2cBus& bus, uint8_t slot);

// Check the chip's identity and write its configuration; false when it did not answer.
bool sensor_init(I2cBus& bus, Sensor s);

// Read one sample in chip axes (x, y, z). False when the chip did not answer or the data is
// invalid (out of the chip's range, magnetometer overflow, or all bytes 0xFF).
bool sensor_read(I2cBus& bus, Sensor s, int16_t chip[AXES]);

}  // namespace bpms

#endif  // BPMS_SENSORS_H
