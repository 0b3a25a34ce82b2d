/* A tripod gait for the hexapod of seed 003, written as STM32Cube firmware for the
 * STM32F411: AX-12 servos (Dynamixel Protocol 1.0) on USART2 in half duplex behind a
 * direction buffer on PA1 (high: transmit), the six leg switches on PB0-PB5 (pressed:
 * low). The same source builds for the board and, against hexhil's C SDK, for the host:
 *
 *   hexhil sdk build examples/c_tripod/main.c -o c_tripod
 *   hexhil run scenarios/flat-tripod.toml --firmware ./c_tripod
 *
 * Each 20 ms cycle: the switches are sampled (debounced over two cycles), every leg's foot
 * target follows the tripod gait (Fig. 13: LM, RF, RH swing in the first half of the
 * period, LF, LH, RM in the second), inverse kinematics turns it into goal positions, one
 * SYNC WRITE sends all 18, and three servos are polled for their present position. A leg
 * whose switch fired since its last lift-off takes the obstacle step at its next lift-off:
 * l_k = 2 l_i (Eq. 6), h_k = H + 2 cm (Eq. 7); a step without contact goes back to l_i, h_i.
 * IDs, the neutral stance and the signs are docs/servo-bus.md's quick reference. */
#include "stm32f4xx_hal.h"

#include <math.h>
#include <string.h>

UART_HandleTypeDef huart2;

/* ---- the robot (seed 003, Fig. 12; docs/servo-bus.md) -------------------------------- */
#define LEGS 6                      /* LF, LM, LH, RF, RM, RH; leg i: IDs 3i+1..3i+3 */
#define COXA_M 0.05f
#define FEMUR_M 0.082f
#define TIBIA_M 0.12f
#define STANCE_DEPTH_M 0.085f       /* 8 cm clearance + 1.5 cm half body - 1 cm foot radius */
#define NEUTRAL_REACH_M 0.15f       /* neutral foot: this far out along the mounting yaw */
#define PI_F 3.14159265f
#define UNITS_PER_RAD (1023.0f / (300.0f * PI_F / 180.0f))   /* AX-12: 1023 over 300 deg */

static const float MOUNT[LEGS][3] = {   /* x_m, y_m, yaw_rad of each coxa joint */
    {0.10f, 0.06f, PI_F / 4}, {0.0f, 0.075f, PI_F / 2}, {-0.10f, 0.06f, 3 * PI_F / 4},
    {0.10f, -0.06f, -PI_F / 4}, {0.0f, -0.075f, -PI_F / 2}, {-0.10f, -0.06f, -3 * PI_F / 4},
};
static const uint8_t SWING_HALF[LEGS] = {1, 0, 1, 0, 1, 0};  /* tripod: half of the swing */

/* ---- the gait (flat-tripod.toml's: seed 003 Sec. 3.3) -------------------------------- */
#define CYCLE_MS 20u
#define PERIOD_S 2.778f             /* 0.036 m/s at l_i = 5 cm */
#define STEP_LENGTH_M 0.05f         /* l_i, Eq. 1 and 16 */
#define STEP_HEIGHT_M 0.03f         /* h_i */
#define MAX_OBSTACLE_M 0.05f        /* H of Eq. 7 (Eq. 16: H <= 5 cm) */
#define STAND_S 1.0f                /* from the sagged pose to the stance */
#define READS_PER_CYCLE 3

/* ---- Dynamixel Protocol 1.0 ---------------------------------------------------------- */
#define BROADCAST 0xFE
#define INST_WRITE 0x03
#define INST_READ 0x02
#define INST_SYNC_WRITE 0x83
#define ADDR_TORQUE_ENABLE 24
#define ADDR_GOAL_POSITION 30
#define ADDR_PRESENT_POSITION 36
#define REPLY_TIMEOUT_MS 10u

static uint8_t packet[4 + 2 + 2 + 18 * 3 + 1];

static uint16_t make_packet(uint8_t id, uint8_t inst, const uint8_t *params, uint8_t n)
{
    uint8_t sum = id + (uint8_t)(n + 2) + inst;
    packet[0] = packet[1] = 0xFF;
    packet[2] = id;
    packet[3] = (uint8_t)(n + 2);
    packet[4] = inst;
    for (uint8_t i = 0; i < n; i++) {
        packet[5 + i] = params[i];
        sum += params[i];
    }
    packet[5 + n] = (uint8_t)~sum;
    return (uint16_t)(n + 6);
}

static void send_packet(uint16_t len)
{
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_SET);
    HAL_HalfDuplex_EnableTransmitter(&huart2);
    HAL_UART_Transmit(&huart2, packet, len, 10);
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_RESET);
    HAL_HalfDuplex_EnableReceiver(&huart2);
}

/* One instruction and its status packet; its parameters in `out`. HAL_OK or the error. */
static HAL_StatusTypeDef transact(uint8_t id, uint8_t inst, const uint8_t *params,
                                  uint8_t n, uint8_t *out, uint8_t nout)
{
    uint8_t status[6 + 8];
    send_packet(make_packet(id, inst, params, n));
    HAL_StatusTypeDef st = HAL_UART_Receive(&huart2, status, (uint16_t)(6 + nout),
                                            REPLY_TIMEOUT_MS);
    if (st != HAL_OK)
        return st;
    uint8_t sum = 0;
    for (int i = 2; i < 5 + nout; i++)
        sum += status[i];
    if (status[0] != 0xFF || status[1] != 0xFF || status[2] != id ||
        (uint8_t)~sum != status[5 + nout])
        return HAL_ERROR;
    memcpy(out, status + 5, nout);
    return HAL_OK;
}

/* ---- kinematics ---------------------------------------------------------------------- */
static float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

static uint16_t to_units(float servo_rad)
{
    return (uint16_t)clampf(roundf(511.5f + servo_rad * UNITS_PER_RAD), 0.0f, 1023.0f);
}

/* Goal positions of leg `leg` for a foot at (x, y, z) in the body frame (knee up). */
static void leg_ik(int leg, float x, float y, float z, uint16_t goal[3])
{
    float c = cosf(MOUNT[leg][2]), s = sinf(MOUNT[leg][2]);
    float dx = x - MOUNT[leg][0], dy = y - MOUNT[leg][1];
    float lx = c * dx + s * dy, ly = -s * dx + c * dy;
    float r = sqrtf(lx * lx + ly * ly) - COXA_M;
    float d = clampf(sqrtf(r * r + z * z), TIBIA_M - FEMUR_M + 1e-4f, FEMUR_M + TIBIA_M - 1e-4f);
    float a = clampf((FEMUR_M * FEMUR_M + d * d - TIBIA_M * TIBIA_M) / (2 * FEMUR_M * d), -1, 1);
    float b = clampf((FEMUR_M * FEMUR_M + TIBIA_M * TIBIA_M - d * d) / (2 * FEMUR_M * TIBIA_M),
                     -1, 1);
    float q1 = atan2f(ly, lx);
    float q2 = atan2f(z, r) + acosf(a);
    float q3 = acosf(b) - PI_F;
    goal[0] = to_units(q1);                 /* joint zeros: coxa 0, femur 0, tibia -pi/2 */
    goal[1] = to_units(q2);
    goal[2] = to_units(q3 + PI_F / 2);
}

/* ---- the switches and the obstacle rule (Eq. 5-7) ------------------------------------ */
struct leg_state {
    float step_m, height_m;   /* this step's l and h, latched at lift-off */
    float lift_x_m;           /* foot x offset at lift-off */
    float land_x_m;           /* foot x offset at touch-down */
    uint8_t swinging, contact, raw, count, pressed;
};
static struct leg_state legs[LEGS];

static void sample_switches(void)
{
    for (int i = 0; i < LEGS; i++) {
        uint8_t level = HAL_GPIO_ReadPin(GPIOB, (uint16_t)(1u << i)) == GPIO_PIN_RESET;
        struct leg_state *g = &legs[i];
        g->count = level == g->raw ? (uint8_t)(g->count < 2 ? g->count + 1 : 2) : 1;
        g->raw = level;
        if (g->count >= 2)
            g->pressed = level;
        if (g->pressed)
            g->contact = 1;
    }
}

/* Foot offset (x forward, z up) of leg `i` at gait phase `phase` in [0, 1). */
static void foot(int i, float phase, float *x, float *z)
{
    struct leg_state *g = &legs[i];
    float u = 2.0f * phase - (float)SWING_HALF[i];   /* 0..1 within this leg's swing half */
    int swing = u >= 0.0f && u < 1.0f;
    if (swing && !g->swinging) {                     /* lift-off: latch l and h */
        int hit = g->contact || g->pressed;
        g->step_m = hit ? 2.0f * STEP_LENGTH_M : STEP_LENGTH_M;
        g->height_m = hit ? MAX_OBSTACLE_M + 0.02f : STEP_HEIGHT_M;
        g->contact = 0;
        g->lift_x_m = g->land_x_m - STEP_LENGTH_M;   /* where the stance left the foot */
        g->land_x_m = g->step_m / 2;
    }
    g->swinging = (uint8_t)swing;
    if (swing) {
        float k = u - sinf(2 * PI_F * u) / (2 * PI_F);   /* cycloid: no jerk at the ends */
        *x = g->lift_x_m + (g->land_x_m - g->lift_x_m) * k;
        *z = g->height_m * 0.5f * (1.0f - cosf(2 * PI_F * u));
    } else {
        float v = u < 0.0f ? u + 1.0f : u - 1.0f;        /* 0..1 within the stance half */
        *x = g->land_x_m - STEP_LENGTH_M * v;
        *z = 0.0f;
    }
}

/* ---- the board ----------------------------------------------------------------------- */
static void board_init(void)
{
    GPIO_InitTypeDef io = {0};
    HAL_Init();
    __HAL_RCC_GPIOA_CLK_ENABLE();
    __HAL_RCC_GPIOB_CLK_ENABLE();
    __HAL_RCC_USART2_CLK_ENABLE();
    io.Pin = GPIO_PIN_1;
    io.Mode = GPIO_MODE_OUTPUT_PP;
    io.Speed = GPIO_SPEED_FREQ_HIGH;
    HAL_GPIO_Init(GPIOA, &io);
    io.Pin = GPIO_PIN_0 | GPIO_PIN_1 | GPIO_PIN_2 | GPIO_PIN_3 | GPIO_PIN_4 | GPIO_PIN_5;
    io.Mode = GPIO_MODE_INPUT;
    io.Pull = GPIO_PULLUP;
    HAL_GPIO_Init(GPIOB, &io);
    huart2.Instance = USART2;
    huart2.Init.BaudRate = 1000000;
    huart2.Init.WordLength = UART_WORDLENGTH_8B;
    huart2.Init.StopBits = UART_STOPBITS_1;
    huart2.Init.Parity = UART_PARITY_NONE;
    huart2.Init.Mode = UART_MODE_TX_RX;
    huart2.Init.HwFlowCtl = UART_HWCONTROL_NONE;
    huart2.Init.OverSampling = UART_OVERSAMPLING_16;
    HAL_HalfDuplex_Init(&huart2);
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_RESET);
}

static void wait_until(uint32_t tick_ms)
{
    uint32_t now = HAL_GetTick();
    if ((int32_t)(tick_ms - now) > 1)
        HAL_Delay(tick_ms - now - 1);   /* HAL_Delay waits one tick more than asked */
    while ((int32_t)(tick_ms - HAL_GetTick()) > 0) {
    }
}

static void sync_write_goals(const uint16_t goal[LEGS * 3])
{
    uint8_t params[2 + LEGS * 3 * 3];
    params[0] = ADDR_GOAL_POSITION;
    params[1] = 2;
    for (int k = 0; k < LEGS * 3; k++) {
        params[2 + 3 * k] = (uint8_t)(k + 1);
        params[3 + 3 * k] = goal[k] & 0xFF;
        params[4 + 3 * k] = goal[k] >> 8;
    }
    send_packet(make_packet(BROADCAST, INST_SYNC_WRITE, params, sizeof params));
}

static void stance_goals(float phase, uint16_t goal[LEGS * 3])
{
    for (int i = 0; i < LEGS; i++) {
        float x, z;
        foot(i, phase, &x, &z);
        float yaw = MOUNT[i][2];
        leg_ik(i, MOUNT[i][0] + NEUTRAL_REACH_M * cosf(yaw) + x,
               MOUNT[i][1] + NEUTRAL_REACH_M * sinf(yaw), z - STANCE_DEPTH_M, &goal[3 * i]);
    }
}

int main(void)
{
    uint16_t start[LEGS * 3], goal[LEGS * 3];
    uint8_t one = 1, pos[2];
    board_init();
    for (uint8_t id = 1; id <= LEGS * 3; id++) {   /* torque on; where each horn sagged to */
        uint8_t torque[2] = {ADDR_TORQUE_ENABLE, one};
        uint8_t read[2] = {ADDR_PRESENT_POSITION, 2};
        transact(id, INST_WRITE, torque, 2, pos, 0);
        start[id - 1] = transact(id, INST_READ, read, 2, pos, 2) == HAL_OK
                        ? (uint16_t)(pos[0] | pos[1] << 8) : 512;
    }
    for (int i = 0; i < LEGS; i++)
        legs[i].land_x_m = STEP_LENGTH_M / 2;
    uint32_t tick = HAL_GetTick();
    uint32_t stand_cycles = (uint32_t)(STAND_S * 1000.0f) / CYCLE_MS;
    for (uint32_t cycle = 0;; cycle++) {
        sample_switches();
        if (cycle < stand_cycles) {                 /* stand up: sagged pose -> stance */
            float k = (float)(cycle + 1) / (float)stand_cycles;
            stance_goals(0.999f, goal);
            for (int j = 0; j < LEGS * 3; j++)
                goal[j] = (uint16_t)roundf(start[j] + (goal[j] - (float)start[j]) * k);
        } else {
            float t_s = (float)((cycle - stand_cycles) * CYCLE_MS) / 1000.0f;
            stance_goals(fmodf(t_s / PERIOD_S, 1.0f), goal);
        }
        sync_write_goals(goal);
        for (int r = 0; r < READS_PER_CYCLE; r++) {
            uint8_t id = (uint8_t)((cycle * READS_PER_CYCLE + r) % (LEGS * 3) + 1);
            uint8_t read[2] = {ADDR_PRESENT_POSITION, 2};
            transact(id, INST_READ, read, 2, pos, 2);
        }
        tick += CYCLE_MS;
        wait_until(tick);
    }
}
