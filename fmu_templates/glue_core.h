/* What fmi2_glue.c and fmi3_glue.c share: the instance and its modes, logging, mode checks,
 * the FMU state (its payload checks and serialisation), initialisation and the step. Written
 * once, for either FMI version: a glue passes in its version's status values, magic numbers,
 * serial format and logger call (GlueVersion), and the core returns and logs those values, so
 * it needs neither version's header. Every function here is internal to the FMU binary
 * (hidden symbols); only the glue's fmi2... or fmi3... functions are exported.
 *
 * The statuses are ints holding the version's values: FMI 2.0 and 3.0 number OK, Warning,
 * Discard, Error and Fatal alike, but the core never relies on it.
 */
#ifndef GATETWIN_GLUE_CORE_H
#define GATETWIN_GLUE_CORE_H

#include <stddef.h>

#include "component.h"

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INITIALIZATION = 2,
    MODE_STEP = 4, /* FMI 2.0's stepComplete, FMI 3.0's step mode */
    MODE_TERMINATED = 8,
    MODE_ERROR = 16
} Mode;

#define ANY_MODE \
    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)

typedef struct GlueSink GlueSink;

/* What a glue tells the core about its FMI version. */
typedef struct {
    int ok, warning, discard, error;      /* the version's status values */
    unsigned instance_magic, state_magic; /* tell its instances and states from other memory */
    char serial_format[17];               /* the first bytes of a serialised state */
    /* Hands one message to the importer's logger (sink->callbacks.logger, cast back). */
    void (*emit)(const GlueSink *sink, int status, const char *category, const char *text);
} GlueVersion;

/* The importer's callbacks as the glue stores them; `logger` is the version's logger type,
 * which only the glue's `emit` calls. */
typedef struct {
    void *environment;
    void (*logger)(void);
    void *(*allocate)(size_t n, size_t size);
    void (*release)(void *p);
} GlueCallbacks;

/* Where messages go: small, so an instantiate function can log before allocating. */
struct GlueSink {
    char name[128];
    const GlueVersion *version;
    GlueCallbacks callbacks;
    int logging_on;
};

typedef struct {
    unsigned magic;
    GlueSink sink;
    Mode mode;
    ModelData data;
} Instance;

/* --- logging --- */
void glue_sink_init(GlueSink *sink, const GlueVersion *version, const char *instance_name,
                    int logging_on);
/* Warnings and errors always; OK messages only when logging is on. */
void glue_log(const GlueSink *sink, int status, const char *text);
#if defined(__GNUC__)
#define GLUE_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define GLUE_PRINTF(f, a)
#endif
void glue_log_format(const GlueSink *sink, int status, const char *format, ...) GLUE_PRINTF(3, 4);
/* Log why, enter the error state, return the error status. */
int glue_fail(Instance *inst, const char *format, ...) GLUE_PRINTF(2, 3);
/* Log why and return the error status, leaving the instance as it was (refused FMU states). */
int glue_refuse(Instance *inst, const char *format, ...) GLUE_PRINTF(2, 3);

/* --- instances and modes --- */
/* The instance behind c if c is one of `version`'s and the call is legal in its mode, else
 * NULL (an illegal call is logged and enters the error state). */
Instance *glue_checked(void *c, const GlueVersion *version, const char *function,
                       unsigned allowed_modes);
/* A new instance, instantiated with the component's defaults; NULL (logged) without memory. */
Instance *glue_new_instance(const GlueSink *sink, const char *function);
void glue_free_instance(Instance *inst);
int glue_set_debug_logging(Instance *inst, const char *function, int logging_on,
                           size_t n_categories, const char *const categories[]);
int glue_exit_initialization(Instance *inst);
void glue_reset(Instance *inst);
/* Status of a component call, logged; errors enter the error state. */
int glue_report(Instance *inst, PlantStatus status, const PlantMessage *msg);

/* --- values --- */
/* NULL arrays (when nvr > 0) or a count of values other than one per value reference. */
int glue_check_arrays(Instance *inst, const char *function, const void *vr, size_t nvr,
                      const void *values, size_t n_values);
/* The value of the component's Real variable vr (< GT_N_REAL). */
int glue_get_real(Instance *inst, const char *function, unsigned vr, double *value);
/* Sets the component's Real variable vr (< GT_N_REAL), or fails saying why it cannot. */
int glue_set_real(Instance *inst, const char *function, unsigned vr, double value);

/* --- FMU state --- */
int glue_get_state(Instance *inst, const char *function, void **state);
int glue_set_state(Instance *inst, const char *function, void *state);
int glue_free_state(Instance *inst, const char *function, void **state);
int glue_serialized_size(Instance *inst, const char *function, size_t *size);
int glue_serialize(Instance *inst, const char *function, void *state, void *bytes, size_t size);
/* Refused bytes leave *state and the instance as they were. */
int glue_deserialize(Instance *inst, const char *function, const void *bytes, size_t size,
                     void **state);

/* --- the step --- */
/* One communication step from currentCommunicationPoint, which must be the FMU's time. */
int glue_do_step(Instance *inst, const char *function, double current_point_s, double step_s);

#endif
