/* The conformance script (docs/link.md "Conformance suite") spoken by the C SDK's link
 * client, firmware/c_sdk/src/hexhil_link.c: hil/link/client_conformance.py serves it
 * (tests/test_c_sdk.py builds it and runs the suite through HEXHIL_LINK_CLIENT). */
#include "hexhil_link.h"

#include <stdio.h>
#include <string.h>

#define PROBE_OP 0x7A    /* an op no version of the link defines */
#define CYCLE_US 20000

/* The string value of "key" in the flat config JSON (json.dumps: `"key": "value"`). */
static void json_str(const char *json, const char *key, char *out, size_t n)
{
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\": \"", key);
    const char *p = strstr(json, pat);
    size_t i = 0;
    if (p)
        for (p += strlen(pat); *p && *p != '"' && i + 1 < n; p++)
            out[i++] = *p;
    out[i] = 0;
}

int main(void)
{
    char probe[32], token[256], text[32];
    uint8_t rx[4], data[8], dlc;
    uint16_t id;

    hx_link_open("c");
    json_str(hx_link_config(), "probe", probe, sizeof probe);
    if (strcmp(probe, "unknown_op") == 0)
        hx_link_post(PROBE_OP, "", 0);
    json_str(hx_link_config(), "token", token, sizeof token);
    hx_link_event(HX_EVENT_LOG, token);
    uint16_t got = hx_link_transact((const uint8_t *)"\x01\x02\x03", 3, rx, 4, 500);
    hx_link_post(HX_OP_WRITE, rx, got);
    for (;;) {
        uint8_t flags = hx_link_sleep(hx_link_t_us() + CYCLE_US);
        if (flags & HX_FLAG_END)
            break;
        while (hx_link_can_recv(&id, data, &dlc))
            hx_link_can_send(id, data, dlc);
        snprintf(text, sizeof text, "switches %u", hx_link_switches());
        hx_link_event(HX_EVENT_LOG, text);
    }
    hx_link_close();
    return 0;
}
