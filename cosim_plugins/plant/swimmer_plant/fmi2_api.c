/* FMI 2.0 Co-Simulation interface of the swimmer plant (modelIdentifier swimmer_plant). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"


/* Log through the environment's logger. The message is formatted here and
 * passed without format directives, so a logger that does not expand
 * variadic arguments prints it unchanged. */
void instance_log(Instance *in, fmi2Status status, const char *category, const char *fmt, ...)
{
    if (!in || !in->cb.logger) return;
    if (status == fmi2OK && !in->logging_on) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    for (char *c = buf; *c; ++c)
        if (*c == '%') *c = ' ';
    in->cb.logger(in->cb.componentEnvironment, in->name, status, category, buf);
}

fmi2Status instance_fail(Instance *in, const char *msg)
{
    instance_log(in, fmi2Error, "logStatusError", "%s", msg);
    return fmi2Error;
}

int instance_usable(Instance *in, const char *fn)
{
    if (!in) return 0;
    if (in->mode == MODE_ERROR) {
        instance_log(in, fmi2Error, "logStatusError", "%s: the instance is in the error state", fn);
        return 0;
    }
    return 1;
}

/* ------------------------------------------------------ version, logging */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    Instance *in = (Instance *)c;
    if (!in) return fmi2Error;
    in->logging_on = loggingOn;
    return fmi2OK;
}

/* --------------------------------------------------------------- lifecycle */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation; (void)visible;
    if (!functions || !functions->logger) return NULL;
    const char *name = instanceName ? instanceName : "swimmer_plant";
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "swimmer_plant supports Co-Simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GUID) != 0) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "GUID does not match this binary; rebuild the FMU");
        return NULL;
    }
    Instance *in = (Instance *)calloc(1, sizeof(Instance));
    if (!in) return NULL;
    in->cb = *functions;
    snprintf(in->name, sizeof(in->name), "%s", name);
    in->logging_on = loggingOn;
    plant_defaults(&in->pl);
    in->mode = MODE_INSTANTIATED;
    return in;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2SetupExperiment")) return fmi2Error;
    if (!isfinite(startTime)) return instance_fail(in, "fmi2SetupExperiment: startTime is not finite");
    in->start_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2EnterInitializationMode")) return fmi2Error;
    in->mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2ExitInitializationMode")) return fmi2Error;
    char msg[400];
    if (plant_validate(&in->pl, msg, sizeof(msg)) || plant_check_inputs(&in->pl, msg, sizeof(msg))) {
        in->mode = MODE_ERROR;
        return instance_fail(in, msg);
    }
    plant_start(&in->pl, in->start_time);
    in->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *in = (Instance *)c;
    if (!in) return fmi2Error;
    in->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *in = (Instance *)c;
    if (!in) return fmi2Error;
    plant_defaults(&in->pl);
    in->start_time = 0.0;
    in->mode = MODE_INSTANTIATED;
    return fmi2OK;
}

/* ---------------------------------------------------------- get and set */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2GetReal")) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= N_REAL) return instance_fail(in, "fmi2GetReal: unknown value reference");
        value[i] = in->pl.r[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2SetReal")) return fmi2Error;
    if (in->mode == MODE_TERMINATED) return instance_fail(in, "fmi2SetReal: the instance is terminated");
    int before_step = in->mode == MODE_INSTANTIATED || in->mode == MODE_INIT;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] >= N_REAL) return instance_fail(in, "fmi2SetReal: unknown value reference");
        int kind = plant_real_kinds[vr[i]];
        const char *name = plant_real_names[vr[i]];
        if (kind == OUT) {
            instance_log(in, fmi2Error, "logStatusError", "fmi2SetReal: %s is an output", name);
            return fmi2Error;
        }
        if (kind == PAR && !before_step) {
            instance_log(in, fmi2Error, "logStatusError",
                    "fmi2SetReal: parameter %s is fixed after initialization", name);
            return fmi2Error;
        }
        if (!isfinite(value[i])) {
            instance_log(in, fmi2Error, "logStatusError", "fmi2SetReal: %s %s is not a finite number",
                    kind == IN ? "input" : "parameter", name);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nvr; ++i) in->pl.r[vr[i]] = value[i];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2GetBoolean")) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] < BOOL_VR_BASE || vr[i] >= BOOL_VR_BASE + N_BOOL)
            return instance_fail(in, "fmi2GetBoolean: unknown value reference");
        value[i] = in->pl.b[vr[i] - BOOL_VR_BASE] ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2SetBoolean")) return fmi2Error;
    int before_step = in->mode == MODE_INSTANTIATED || in->mode == MODE_INIT;
    for (size_t i = 0; i < nvr; ++i) {
        if (vr[i] < BOOL_VR_BASE || vr[i] >= BOOL_VR_BASE + N_BOOL)
            return instance_fail(in, "fmi2SetBoolean: unknown value reference");
        int k = vr[i] - BOOL_VR_BASE;
        if (plant_bool_kinds[k] == PAR && !before_step) {
            instance_log(in, fmi2Error, "logStatusError",
                    "fmi2SetBoolean: parameter %s is fixed after initialization", plant_bool_names[k]);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nvr; ++i) in->pl.b[vr[i] - BOOL_VR_BASE] = value[i] ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    (void)vr; (void)value;
    return nvr ? instance_fail((Instance *)c, "fmi2GetInteger: the FMU has no Integer variables") : fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    (void)vr; (void)value;
    return nvr ? instance_fail((Instance *)c, "fmi2SetInteger: the FMU has no Integer variables") : fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)vr; (void)value;
    return nvr ? instance_fail((Instance *)c, "fmi2GetString: the FMU has no String variables") : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)vr; (void)value;
    return nvr ? instance_fail((Instance *)c, "fmi2SetString: the FMU has no String variables") : fmi2OK;
}

/* -------------------------------------------------------- co-simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2DoStep")) return fmi2Error;
    if (in->mode != MODE_STEP) return instance_fail(in, "fmi2DoStep: call fmi2ExitInitializationMode first");
    char msg[400];
    if (!(communicationStepSize >= 0.0) || !isfinite(communicationStepSize)) {
        instance_log(in, fmi2Error, "logStatusError", "fmi2DoStep: step size %g must be >= 0",
                communicationStepSize);
        return fmi2Error;
    }
    double t = in->pl.t;
    if (!(fabs(currentCommunicationPoint - t) <= 1e-9 * fmax(1.0, fabs(t)))) {
        instance_log(in, fmi2Error, "logStatusError",
                "fmi2DoStep: communication point %.12g differs from the FMU time %.12g",
                currentCommunicationPoint, t);
        return fmi2Error;
    }
    if (plant_check_inputs(&in->pl, msg, sizeof(msg)) || plant_validate(&in->pl, msg, sizeof(msg)))
        return instance_fail(in, msg);
    if (plant_step(&in->pl, communicationStepSize, msg, sizeof(msg))) {
        in->mode = MODE_ERROR;
        return instance_fail(in, msg);
    }
    return fmi2OK;
}

/* ------------------------------------------------ test hook (not FMI) */

/* Field per ampere G[6][3] [T/A] and gradient J[6][3][3] [T/(A m)] of the
 * default-shaped coils at p [m]; lets tests check the magnetics directly. */
FMI2_Export void swimmer_plant_coil_fields(double turns, double r_inner, double r_outer,
                                           double thickness, double cube_half, const double p[3],
                                           double G[18], double J[54])
{
    CoilGeom g;
    coil_geom_init(&g, turns, r_inner, r_outer, thickness, cube_half);
    coil_fields(&g, p, (double (*)[3])G, (double (*)[3][3])J);
}
