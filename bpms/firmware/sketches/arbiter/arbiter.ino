// BPMS arbiter board (ATmega328P, 16 MHz): host commands over the RN-41 Bluetooth module,
// polls the six clusters through two 74HC4051 multiplexers and streams 340-byte frames every
// 20 ms. Logic: bpms_core/arbiter_logic.cpp. Wiring: docs/firmware.md.
#include <Arduino.h>

#include "arduino_glue.h"
#include "board_config.h"
#include "bpms_core/arbiter_logic.h"

namespace {

class Board : public bpms::ArbiterBoard {
public:
    void begin() {
        pinMode(ARBITER_SEL0_PIN, OUTPUT);
        pinMode(ARBITER_SEL1_PIN, OUTPUT);
        pinMode(ARBITER_SEL2_PIN, OUTPUT);
        pinMode(ARBITER_RADIO_CTS_PIN, OUTPUT);
        digitalWrite(ARBITER_RADIO_CTS_PIN, HIGH);
        analogReference(DEFAULT);  // AVcc = 3.3 V
        analogRead(ARBITER_BATTERY_PIN);  // first conversion after a reference change is junk
    }
    void select_channel(uint8_t channel) override {
        digitalWrite(ARBITER_SEL0_PIN, (channel & 1) ? HIGH : LOW);
        digitalWrite(ARBITER_SEL1_PIN, (channel & 2) ? HIGH : LOW);
        digitalWrite(ARBITER_SEL2_PIN, (channel & 4) ? HIGH : LOW);
    }
    void hold_radio(bool hold) override {
        digitalWrite(ARBITER_RADIO_CTS_PIN, hold ? HIGH : LOW);
    }
    uint16_t read_battery_adc() override {
        return static_cast<uint16_t>(analogRead(ARBITER_BATTERY_PIN));
    }
};

Board board;
bpms::HardwareSerialPort port(Serial);
bpms::ArduinoClock clock_source;
bpms::PinOut stream_led(ARBITER_STREAM_LED_PIN);
bpms::ArbiterLogic arbiter(port, board, clock_source, stream_led);

}  // namespace

void setup() {
    bpms::power_down_unused(/*keep_adc=*/true, /*keep_twi=*/false);
    stream_led.begin();
    board.begin();
    Serial.begin(BPMS_BAUD);
    arbiter.begin();
}

void loop() {
    arbiter.loop();
}
