// BPMS cluster board (ATmega328P, 16 MHz): three SEN-10724 sensor sticks behind a TCA9548A
// I2C multiplexer; answers each poll from the arbiter with the reading stored at the previous
// poll, then samples anew. Logic: bpms_core/cluster_logic.cpp. Wiring: docs/firmware.md.
#include <Arduino.h>
#include <Wire.h>

#include "arduino_glue.h"
#include "board_config.h"
#include "bpms_core/cluster_logic.h"

namespace {

class WireBus : public bpms::I2cBus {
public:
    bool write(uint8_t addr, const uint8_t* data, uint8_t n) override {
        Wire.beginTransmission(addr);
        Wire.write(data, n);
        return Wire.endTransmission() == 0;
    }
    uint8_t read(uint8_t addr, uint8_t* data, uint8_t n) override {
        uint8_t got = Wire.requestFrom(addr, n);
        uint8_t i = 0;
        while (i < got && Wire.available()) data[i++] = static_cast<uint8_t>(Wire.read());
        return i;
    }
};

WireBus bus;
bpms::HardwareSerialPort port(Serial);
bpms::PinOut error_led(CLUSTER_ERROR_LED_PIN);
bpms::ClusterLogic cluster(bus, port, error_led);

}  // namespace

void setup() {
    bpms::power_down_unused(/*keep_adc=*/false, /*keep_twi=*/true);
    error_led.begin();
    error_led.set(true);  // lit until the first reading proves every sensor answers
    Serial.begin(BPMS_BAUD);
    Wire.begin();
    Wire.setClock(BPMS_I2C_HZ);
    Wire.setWireTimeout(BPMS_I2C_TIMEOUT_US, true);
    delay(60);  // ITG-3200 start-up time after power-on
    cluster.begin();
}

void loop() {
    cluster.loop();
}
