/* The FMI glue written once for FMI 2.0 and 3.0 (see glue_core.h): logging, mode checks, the
 * instance's life, getting and setting Real variables, the FMU state and the step.
 *
 * A restored state is checked completely before it is used (plant_check_state): identity
 * (the GUID or instantiation token in a serialised state's header, the library that made an
 * in-memory one), format version and size, mode, every flag, index and count, every double
 * finite. A refused state leaves the instance as it was, in its mode.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "glue_core.h"

/* What an FMU state holds and serialises: everything in ModelData and the mode it was taken
 * in. */
typedef struct {
    Mode mode;
    ModelData data;
} StatePayload;

/* An FMU state in memory; `owner` tells states of this library from another FMU's. */
typedef struct {
    unsigned magic;
    const void *owner;
    StatePayload payload;
} StoredState;

#define STATE_OWNER ((const void *)plant_variables)

typedef struct {
    char format[17]; /* GlueVersion.serial_format */
    char token[64];  /* GT_GUID: a state only fits the build it came from */
    unsigned long long payload_size;
} SerialHeader;

/* Bytes of a serialised state: the header, then the payload. */
#define SERIAL_SIZE (sizeof(SerialHeader) + sizeof(StatePayload))

/* --- logging --------------------------------------------------------------------------------- */

void glue_sink_init(GlueSink *sink, const GlueVersion *version, const char *instance_name,
                    int logging_on)
{
    memset(sink, 0, sizeof *sink);
    sink->version = version;
    sink->logging_on = logging_on;
    snprintf(sink->name, sizeof sink->name, "%s", instance_name ? instance_name : "(NULL)");
}

void glue_log(const GlueSink *sink, int status, const char *text)
{
    const GlueVersion *v = sink->version;
    const char *category = "logStatusError";
    if (!sink->callbacks.logger || (status == v->ok && !sink->logging_on)) {
        return;
    }
    if (status == v->ok) {
        category = "logAll";
    } else if (status == v->warning || status == v->discard) {
        category = "logStatusWarning";
    }
    v->emit(sink, status, category, text);
}

#if defined(__GNUC__)
static void log_formatted(const GlueSink *sink, int status, const char *format, va_list args)
    __attribute__((format(printf, 3, 0)));
#endif

static void log_formatted(const GlueSink *sink, int status, const char *format, va_list args)
{
    char text[768];
    vsnprintf(text, sizeof text, format, args);
    glue_log(sink, status, text);
}

void glue_log_format(const GlueSink *sink, int status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    log_formatted(sink, status, format, args);
    va_end(args);
}

int glue_fail(Instance *inst, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    log_formatted(&inst->sink, inst->sink.version->error, format, args);
    va_end(args);
    inst->mode = MODE_ERROR;
    return inst->sink.version->error;
}

int glue_refuse(Instance *inst, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    log_formatted(&inst->sink, inst->sink.version->error, format, args);
    va_end(args);
    return inst->sink.version->error;
}

/* --- instances and modes --------------------------------------------------------------------- */

static const char *mode_name(Mode mode)
{
    switch (mode) {
    case MODE_INSTANTIATED: return "instantiated";
    case MODE_INITIALIZATION: return "initialization mode";
    case MODE_STEP: return "step mode";
    case MODE_TERMINATED: return "terminated";
    default: return "error";
    }
}

Instance *glue_checked(void *c, const GlueVersion *version, const char *function,
                       unsigned allowed_modes)
{
    Instance *inst = (Instance *)c;
    if (!inst || inst->magic != version->instance_magic) {
        return NULL;
    }
    if (!(inst->mode & allowed_modes)) {
        glue_fail(inst, "%s must not be called in %s", function, mode_name(inst->mode));
        return NULL;
    }
    return inst;
}

Instance *glue_new_instance(const GlueSink *sink, const char *function)
{
    Instance *inst = (Instance *)sink->callbacks.allocate(1, sizeof *inst);
    if (!inst) {
        glue_log_format(sink, sink->version->error, "%s: out of memory", function);
        return NULL;
    }
    inst->magic = sink->version->instance_magic;
    inst->sink = *sink;
    inst->mode = MODE_INSTANTIATED;
    plant_set_defaults(&inst->data);
    glue_log(&inst->sink, sink->version->ok, "instantiated " GT_MODEL_IDENTIFIER);
    return inst;
}

void glue_free_instance(Instance *inst)
{
    void (*release)(void *p) = inst->sink.callbacks.release;
    inst->magic = 0;
    release(inst);
}

int glue_set_debug_logging(Instance *inst, const char *function, int logging_on,
                           size_t n_categories, const char *const categories[])
{
    static const char *const known[] = GT_LOG_CATEGORIES;
    size_t i, k;
    if (n_categories > 0 && !categories) {
        return glue_fail(inst, "%s: categories is NULL", function);
    }
    for (i = 0; i < n_categories; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++) {
            found = found || (categories[i] && strcmp(categories[i], known[k]) == 0);
        }
        if (!found) {
            return glue_fail(inst, "%s: unknown log category '%s'", function,
                             categories[i] ? categories[i] : "(NULL)");
        }
    }
    inst->sink.logging_on = logging_on;
    return inst->sink.version->ok;
}

int glue_exit_initialization(Instance *inst)
{
    PlantMessage msg;
    PlantStatus status = plant_initialize(&inst->data, &msg);
    if (status != PLANT_ERROR) {
        inst->mode = MODE_STEP;
    }
    return glue_report(inst, status, &msg);
}

void glue_reset(Instance *inst)
{
    plant_set_defaults(&inst->data);
    inst->mode = MODE_INSTANTIATED;
}

int glue_report(Instance *inst, PlantStatus status, const PlantMessage *msg)
{
    if (status == PLANT_ERROR) {
        return glue_fail(inst, "%s", msg->text);
    }
    if (status == PLANT_WARNING) {
        glue_log(&inst->sink, inst->sink.version->warning, msg->text);
        return inst->sink.version->warning;
    }
    return inst->sink.version->ok;
}

/* --- values ---------------------------------------------------------------------------------- */

int glue_check_arrays(Instance *inst, const char *function, const void *vr, size_t nvr,
                      const void *values, size_t n_values)
{
    if (nvr > 0 && (!vr || !values)) {
        return glue_fail(inst, "%s: NULL value-reference or value array", function);
    }
    if (n_values != nvr) {
        return glue_fail(inst, "%s: %lu values for %lu scalar variables", function,
                         (unsigned long)n_values, (unsigned long)nvr);
    }
    return inst->sink.version->ok;
}

int glue_get_real(Instance *inst, const char *function, unsigned vr, double *value)
{
    if (plant_variables[vr].kind == GT_KIND_OUTPUT) {
        PlantMessage msg;
        if (plant_output(&inst->data, vr, value, &msg) != PLANT_OK) {
            return glue_fail(inst, "%s: %s", function, msg.text);
        }
    } else {
        *value = inst->data.real[vr];
    }
    return inst->sink.version->ok;
}

int glue_set_real(Instance *inst, const char *function, unsigned vr, double value)
{
    const PlantVariable *var = &plant_variables[vr];
    if (var->kind == GT_KIND_OUTPUT) {
        return glue_fail(inst, "%s: %s is an output", function, var->name);
    }
    if (var->kind == GT_KIND_FIXED && inst->mode == MODE_STEP) {
        return glue_fail(inst, "%s: %s is a fixed parameter, settable only before "
                               "initialization mode ends", function, var->name);
    }
    if (!isfinite(value)) { /* every value an FMU state holds stays finite */
        return glue_fail(inst, "%s: %s = %g is not finite", function, var->name, value);
    }
    inst->data.real[vr] = value;
    if (var->kind != GT_KIND_INPUT) {
        inst->data.parameters_changed = 1;
    }
    return inst->sink.version->ok;
}

/* --- FMU state ------------------------------------------------------------------------------- */

/* Whether a stored state can be restored into this FMU: its mode and ModelData (component.h). */
static int check_payload(Instance *inst, const char *function, const StatePayload *p)
{
    PlantMessage msg;
    int initialized;
    switch (p->mode) {
    case MODE_INSTANTIATED:
    case MODE_INITIALIZATION: initialized = 0; break;
    case MODE_STEP:
    case MODE_TERMINATED: initialized = 1; break;
    default:
        return glue_refuse(inst, "%s: the state's mode %d is not a mode a state is taken in",
                           function, (int)p->mode);
    }
    if (plant_check_state(&p->data, initialized, &msg) != PLANT_OK) {
        return glue_refuse(inst, "%s: corrupt state refused, the instance is unchanged: %s",
                           function, msg.text);
    }
    return inst->sink.version->ok;
}

/* The state behind an FMU-state argument if it is one of this library's, else NULL. */
static StoredState *own_state(const Instance *inst, void *state)
{
    StoredState *stored = (StoredState *)state;
    if (!stored || stored->magic != inst->sink.version->state_magic ||
        stored->owner != STATE_OWNER) {
        return NULL;
    }
    return stored;
}

static StoredState *new_state(const Instance *inst)
{
    StoredState *stored = (StoredState *)inst->sink.callbacks.allocate(1, sizeof *stored);
    if (stored) {
        stored->magic = inst->sink.version->state_magic;
        stored->owner = STATE_OWNER;
    }
    return stored;
}

static void free_state(const Instance *inst, StoredState *stored)
{
    stored->magic = 0;
    inst->sink.callbacks.release(stored);
}

int glue_get_state(Instance *inst, const char *function, void **state)
{
    StoredState *stored;
    if (!state) {
        return glue_fail(inst, "%s: FMU state pointer is NULL", function);
    }
    stored = own_state(inst, *state);
    if (*state && !stored) {
        return glue_fail(inst, "%s: *FMU state is not a state of this FMU", function);
    }
    if (!stored) {
        stored = new_state(inst);
        if (!stored) {
            return glue_fail(inst, "%s: out of memory", function);
        }
    }
    stored->payload.mode = inst->mode;
    memcpy(&stored->payload.data, &inst->data, sizeof inst->data);
    *state = stored;
    return inst->sink.version->ok;
}

int glue_set_state(Instance *inst, const char *function, void *state)
{
    const StoredState *stored = own_state(inst, state);
    if (!stored) {
        return glue_refuse(inst, "%s: FMU state is NULL or not a state of this FMU", function);
    }
    if (check_payload(inst, function, &stored->payload) != inst->sink.version->ok) {
        return inst->sink.version->error;
    }
    memcpy(&inst->data, &stored->payload.data, sizeof inst->data);
    inst->mode = stored->payload.mode;
    return inst->sink.version->ok;
}

int glue_free_state(Instance *inst, const char *function, void **state)
{
    StoredState *stored;
    if (!state || !*state) {
        return inst->sink.version->ok;
    }
    stored = own_state(inst, *state);
    if (!stored) {
        return glue_fail(inst, "%s: *FMU state is not a state of this FMU", function);
    }
    free_state(inst, stored);
    *state = NULL;
    return inst->sink.version->ok;
}

int glue_serialized_size(Instance *inst, const char *function, size_t *size)
{
    if (!size) {
        return glue_fail(inst, "%s: size is NULL", function);
    }
    *size = SERIAL_SIZE;
    return inst->sink.version->ok;
}

int glue_serialize(Instance *inst, const char *function, void *state, void *bytes, size_t size)
{
    const StoredState *stored = own_state(inst, state);
    SerialHeader header;
    if (!stored || !bytes) {
        return glue_fail(inst, "%s: NULL buffer, or the FMU state is not a state of this FMU",
                         function);
    }
    if (size != SERIAL_SIZE) {
        return glue_fail(inst, "%s: buffer holds %lu bytes, the state needs %lu", function,
                         (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memset(&header, 0, sizeof header);
    memcpy(header.format, inst->sink.version->serial_format, sizeof header.format);
    snprintf(header.token, sizeof header.token, "%s", GT_GUID);
    header.payload_size = sizeof stored->payload;
    memcpy(bytes, &header, sizeof header);
    memcpy((unsigned char *)bytes + sizeof header, &stored->payload, sizeof stored->payload);
    return inst->sink.version->ok;
}

/* Refuses a header that does not fit this FMU, saying why. */
static int check_header(Instance *inst, const char *function, SerialHeader *header)
{
    const char *format = inst->sink.version->serial_format;
    if (memcmp(header->format, format, sizeof header->format) != 0) {
        return glue_refuse(inst, "%s: not a serialised state of format %s", function, format);
    }
    if (strncmp(header->token, GT_GUID, sizeof header->token) != 0) {
        size_t i;
        header->token[sizeof header->token - 1] = '\0';
        /* the token comes from the caller's bytes: only printable ASCII reaches the log */
        for (i = 0; header->token[i] != '\0'; i++) {
            const unsigned char c = (unsigned char)header->token[i];
            if (c < 0x20 || c > 0x7e) {
                header->token[i] = '?';
            }
        }
        return glue_refuse(inst, "%s: the state is of FMU %s, this FMU is %s", function,
                           header->token, GT_GUID);
    }
    if (header->payload_size != sizeof(StatePayload)) {
        return glue_refuse(inst, "%s: payload of %llu bytes, this FMU's has %lu", function,
                           header->payload_size, (unsigned long)sizeof(StatePayload));
    }
    return inst->sink.version->ok;
}

int glue_deserialize(Instance *inst, const char *function, const void *bytes, size_t size,
                     void **state)
{
    const int ok = inst->sink.version->ok;
    SerialHeader header;
    StoredState *target, *decoded;
    if (!bytes || !state) {
        return glue_refuse(inst, "%s: NULL argument", function);
    }
    target = own_state(inst, *state);
    if (*state && !target) {
        return glue_refuse(inst, "%s: *FMU state is not a state of this FMU", function);
    }
    if (size != SERIAL_SIZE) {
        return glue_refuse(inst, "%s: %lu bytes given, a state of this FMU has %lu", function,
                           (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memcpy(&header, bytes, sizeof header);
    if (check_header(inst, function, &header) != ok) {
        return inst->sink.version->error;
    }
    decoded = new_state(inst);
    if (!decoded) {
        return glue_refuse(inst, "%s: out of memory", function);
    }
    memcpy(&decoded->payload, (const unsigned char *)bytes + sizeof header,
           sizeof decoded->payload);
    if (check_payload(inst, function, &decoded->payload) != ok) {
        free_state(inst, decoded);
        return inst->sink.version->error;
    }
    if (target) {
        memcpy(&target->payload, &decoded->payload, sizeof target->payload);
        free_state(inst, decoded);
        decoded = target;
    }
    *state = decoded;
    return ok;
}

/* --- the step -------------------------------------------------------------------------------- */

int glue_do_step(Instance *inst, const char *function, double current_point_s, double step_s)
{
    PlantMessage msg;
    const double time_s = inst->data.time_s;
    if (!(fabs(current_point_s - time_s) <=
          GT_COMMUNICATION_POINT_RTOL * fmax(1.0, fabs(time_s)))) {
        return glue_fail(inst, "%s: currentCommunicationPoint %.17g s differs from the FMU's "
                               "time %.17g s", function, current_point_s, time_s);
    }
    return glue_report(inst, plant_do_step(&inst->data, step_s, &msg), &msg);
}
