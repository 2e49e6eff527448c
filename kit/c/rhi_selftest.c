/* rhi_selftest: every pack/parse pair of rhi_device.c round-trips, and the COMMAND of docs/protocol.md §7 is
 * byte for byte the one documented. `make check` runs it; it prints "ok" and exits 0, or names what failed. */
#include "rhi_device.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int failures = 0;
#define CHECK(c) do { if (!(c)) { printf("FAILED: %s (line %d)\n", #c, __LINE__); failures++; } } while (0)

int main(void) {
    static const uint8_t doc[52] = {
        0x52, 0x48, 0x49, 0x43, 0x02, 0x00, 0x05, 0x00, 0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11,
        0x05, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x04, 0x40, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0x3f, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0xc0};
    uint8_t buf[2048];
    char why[200];
    rhi_command c, c2;
    rhi_reading r, r2;
    rhi_hello h;
    rhi_info info;
    rhi_error e;
    size_t len;
    int i;

    memset(&c, 0, sizeof c);
    c.flags = RHI_ENABLE | RHI_RESET;
    c.session = 0x1122334455667788ull;
    c.seq = 5;
    c.ack = 4;
    c.n = 2;
    c.t_host = 2.5;
    c.tau[0] = 1.0;
    c.tau[1] = -2.0;
    len = rhi_pack_command(buf, sizeof buf, &c);
    CHECK(len == sizeof doc && memcmp(buf, doc, len) == 0);
    CHECK(rhi_parse_command(buf, len, 2, &c2) == 0 && c2.session == c.session && c2.seq == 5 && c2.ack == 4
          && c2.flags == c.flags && c2.t_host == 2.5 && c2.tau[1] == -2.0);
    CHECK(rhi_parse_command(buf, len - 1, 2, &c2) < 0);   /* length */
    CHECK(rhi_parse_command(buf, len, 3, &c2) < 0);       /* n */
    c.flags = 0x10;
    len = rhi_pack_command(buf, sizeof buf, &c);
    CHECK(rhi_parse_command(buf, len, 2, &c2) < 0);       /* a reserved flag bit */
    c.flags = RHI_ENABLE;
    c.tau[0] = NAN;
    len = rhi_pack_command(buf, sizeof buf, &c);
    CHECK(rhi_parse_command(buf, len, 2, &c2) < 0);       /* non-finite */
    c.tau[0] = 1e300;
    len = rhi_pack_command(buf, sizeof buf, &c);
    CHECK(rhi_parse_command(buf, len, 2, &c2) == 0 && c2.tau[0] == 1e300); /* finite of any size: valid */

    memset(&r, 0, sizeof r);
    r.status = RHI_ENABLED | RHI_SIMULATED;
    r.session = 42;
    r.seq = 9;
    r.cmd_seq = RHI_NO_SEQ;
    r.n = 2;
    r.k = 1;
    r.t_dev = 0.25;
    r.q[0] = 1; r.q[1] = 2; r.dq[0] = 3; r.dq[1] = 4; r.s[0] = 5;
    len = rhi_pack_reading(buf, sizeof buf, &r);
    CHECK(len == RHI_READING_SIZE + 40);
    CHECK(rhi_parse_reading(buf, len, 2, 1, &r2) == 0 && r2.session == 42 && r2.seq == 9 && r2.cmd_seq == RHI_NO_SEQ
          && r2.status == r.status && r2.t_dev == 0.25 && r2.q[1] == 2 && r2.dq[0] == 3 && r2.s[0] == 5);

    len = rhi_pack_hello(buf, sizeof buf, 77, RHI_TAKEOVER);
    CHECK(len == RHI_HELLO_SIZE && rhi_parse_hello(buf, len, &h, why, sizeof why) == 0 && h.session == 77
          && h.flags == RHI_TAKEOVER);
    CHECK(rhi_parse_hello(buf, len + 1, &h, why, sizeof why) < 0 && strstr(why, "17 bytes") != NULL);
    len = rhi_pack_hello(buf, sizeof buf, 0, 0);
    CHECK(rhi_parse_hello(buf, len, &h, why, sizeof why) < 0 && strstr(why, "session id 0") != NULL);
    buf[4] = 1;
    CHECK(rhi_parse_hello(buf, len, &h, why, sizeof why) < 0 && strstr(why, "version 1") != NULL);

    len = rhi_pack_info(buf, sizeof buf, 4, 6, 1000.0, 0.02, 77, "{\"device\": \"d\", \"sensors\": [[\"ft\", 6]]}");
    CHECK(rhi_parse_info(buf, len, &info) == 0 && info.n == 4 && info.k == 6 && info.rate == 1000.0
          && info.watchdog == 0.02 && info.session == 77 && info.json_len == len - RHI_INFO_SIZE);

    len = rhi_pack_error(buf, sizeof buf, RHI_E_BUSY, 77, "busy");
    CHECK(rhi_parse_error(buf, len, &e) == 0 && e.code == RHI_E_BUSY && e.session == 77 && e.message_len == 4
          && memcmp(e.message, "busy", 4) == 0);
    len = rhi_pack_error_v1_0(buf, sizeof buf, "old");
    CHECK(len == 11 && rhi_parse_error(buf, len, &e) == 0 && e.version == 1 && e.code == 0 && e.message_len == 3);

    CHECK(rhi_seq_newer(0, 0xFFFFFFFFu) && rhi_seq_newer(5, 4) && !rhi_seq_newer(4, 4) && !rhi_seq_newer(3, 4));
    for (i = 0; i < 8; i++) CHECK(rhi_pack_hello(buf, (size_t)i, 1, 0) == 0); /* too small: nothing written */
    if (failures) return 1;
    printf("ok\n");
    return 0;
}
