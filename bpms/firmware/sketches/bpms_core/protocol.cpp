#include "protocol.h"

namespace bpms {

uint16_t battery_millivolts(uint32_t adc_sum, uint8_t n, const BatteryDivider& d) {
    if (n == 0 || d.r_bottom == 0) return 0;
    // Largest intermediate: 8 * 1023 * 3300 * 200 ~ 5.4e9 would overflow 32 bits, so scale
    // in two steps (error < 1 mV).
    uint32_t pin_mv_x1024 = adc_sum * d.vref_mv / n;  // <= 1023 * 65535 fits in 32 bits
    uint32_t cell = pin_mv_x1024 / d.r_bottom * (static_cast<uint32_t>(d.r_top) + d.r_bottom)
                    + pin_mv_x1024 % d.r_bottom * (static_cast<uint32_t>(d.r_top) + d.r_bottom)
                          / d.r_bottom;
    cell = (cell + 512) / 1024;
    return cell > 65535u ? 65535u : static_cast<uint16_t>(cell);
}

void format_battery_reply(uint16_t millivolts, uint8_t out[BATTERY_REPLY_BYTES]) {
    // 32-bit sum: on the AVR `unsigned` is 16 bits and 65535 + 5 would wrap to 4.
    uint32_t cv = (static_cast<uint32_t>(millivolts) + 5u) / 10u;  // centivolts, rounded
    if (cv > 999) cv = 999;
    out[0] = 'V';
    out[1] = static_cast<uint8_t>('0' + cv / 100);
    out[2] = '.';
    out[3] = static_cast<uint8_t>('0' + (cv / 10) % 10);
    out[4] = static_cast<uint8_t>('0' + cv % 10);
    out[5] = '\n';
}

}  // namespace bpms
