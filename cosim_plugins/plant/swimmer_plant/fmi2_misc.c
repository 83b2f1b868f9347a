/* FMI 2.0 functions beyond stepping: FMU state, status queries, unsupported calls. */
#include <stdlib.h>
#include <string.h>

#include "instance.h"

#define STATE_MAGIC 0x53574d31u   /* "SWM1": serialized-state tag */


/* ------------------------------------------------------------ FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    Instance *in = (Instance *)c;
    if (!instance_usable(in, "fmi2GetFMUstate")) return fmi2Error;
    Plant *copy = (Plant *)(*state ? *state : malloc(sizeof(Plant)));
    if (!copy) return instance_fail(in, "fmi2GetFMUstate: out of memory");
    *copy = in->pl;
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    Instance *in = (Instance *)c;
    if (!in || !state) return fmi2Error;
    in->pl = *(Plant *)state;
    in->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    if (state) { free(*state); *state = NULL; }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c; (void)state;
    *size = sizeof(unsigned) + sizeof(Plant);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    Instance *in = (Instance *)c;
    unsigned magic = STATE_MAGIC;
    if (!state || size < sizeof(unsigned) + sizeof(Plant)) return instance_fail(in, "fmi2SerializeFMUstate: buffer too small");
    memcpy(bytes, &magic, sizeof(magic));
    memcpy(bytes + sizeof(magic), state, sizeof(Plant));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
{
    Instance *in = (Instance *)c;
    unsigned magic;
    if (size != sizeof(unsigned) + sizeof(Plant)) return instance_fail(in, "fmi2DeSerializeFMUstate: wrong size");
    memcpy(&magic, bytes, sizeof(magic));
    if (magic != STATE_MAGIC) return instance_fail(in, "fmi2DeSerializeFMUstate: not a swimmer_plant state");
    Plant *copy = (Plant *)(*state ? *state : malloc(sizeof(Plant)));
    if (!copy) return instance_fail(in, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(copy, bytes + sizeof(magic), sizeof(Plant));
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return instance_fail((Instance *)c, "fmi2GetDirectionalDerivative is not provided");
}

/* ------------------------------------------------ status and unsupported */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return instance_fail((Instance *)c, "fmi2SetRealInputDerivatives: inputs are not interpolated");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return instance_fail((Instance *)c, "fmi2GetRealOutputDerivatives: not provided");
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    return instance_fail((Instance *)c, "fmi2CancelStep: steps are never asynchronous");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *in = (Instance *)c;
    if (!in) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) { *value = in->pl.t; return fmi2OK; }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)c;
    if (s == fmi2Terminated) { *value = fmi2False; return fmi2OK; }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
