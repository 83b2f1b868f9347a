/* One FMU instance and the logging helpers shared by the FMI 2.0 files. */
#ifndef SWIMMER_INSTANCE_H
#define SWIMMER_INSTANCE_H

#include "fmi2Functions.h"
#include "plant.h"

#define GUID "{8c4e1a52-6b0d-4f5e-9a3c-2d7f1e0b5a91}"

typedef enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED, MODE_ERROR } Mode;

typedef struct {
    Plant pl;
    fmi2CallbackFunctions cb;
    char name[128];
    int logging_on;
    double start_time;
    Mode mode;
} Instance;

/* Log a message (formatted here, passed to the logger without directives). */
void instance_log(Instance *in, fmi2Status status, const char *category, const char *fmt, ...);

/* Log an error and return fmi2Error. */
fmi2Status instance_fail(Instance *in, const char *msg);

/* 0 (after logging) if the instance is missing or in the error state. */
int instance_usable(Instance *in, const char *fn);

#endif
