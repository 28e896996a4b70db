/* The linux64 binary of dsg-hil's FMUs: FMI 2.0 co-simulation around PythonFMU's binary, which returns the status
 * the slave gave a refused call.
 *
 * PythonFMU's binary (0.6.4 to 0.7.0 and its git main, fmi2.cpp) returns fmi2OK for every call whose Python method
 * returns, and fmi2Fatal for every Python exception; a Python slave cannot make it return fmi2Error. dsg-hil's
 * slaves refuse a caller's mistake by logging it with status fmi2Error (dsg_hil/fmi/slave.py). This library is the
 * FMU's binaries/linux64/<modelIdentifier>.so; at fmi2Instantiate it loads PythonFMU's binary from beside itself
 * (<modelIdentifier>_pythonfmu.so, written there by 'dsg-hil fmu export') and instantiates it with a logger of its
 * own, which passes each message on to the host's logger and notes whether one had status fmi2Error. Each call is
 * forwarded; where PythonFMU's binary returned fmi2OK or fmi2Warning and an fmi2Error message was logged during the
 * call (PythonFMU hands the slave's messages to the logger before the call returns: clearLogBuffer), the call
 * returns fmi2Error. fmi2DoStep returns what PythonFMU's returned (a refused step: fmi2Discard).
 *
 * PythonFMU's binary is instantiated with logging on and no categories, so that every message reaches this logger;
 * the host's loggingOn and fmi2SetDebugLogging's categories choose what is passed on, as PythonFMU's logger does.
 *
 * C99 and POSIX's dlopen, nothing else (cc -std=c99 -shared -fPIC shim.c -ldl). */

#define _GNU_SOURCE /* dladdr */
#include <dlfcn.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

/* ---- the FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h; "default" platform) -------------------------- */
typedef void* fmi2Component;
typedef void* fmi2ComponentEnvironment;
typedef void* fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char* fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void* (*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void*);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

/* ---- PythonFMU's functions, as this library calls them -------------------------------------------------------- */
typedef struct {
    fmi2Component (*Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions*,
                                 fmi2Boolean, fmi2Boolean);
    void (*FreeInstance)(fmi2Component);
    fmi2Status (*SetupExperiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
    fmi2Status (*EnterInitializationMode)(fmi2Component);
    fmi2Status (*ExitInitializationMode)(fmi2Component);
    fmi2Status (*Terminate)(fmi2Component);
    fmi2Status (*Reset)(fmi2Component);
    fmi2Status (*GetReal)(fmi2Component, const fmi2ValueReference*, size_t, fmi2Real*);
    fmi2Status (*GetInteger)(fmi2Component, const fmi2ValueReference*, size_t, fmi2Integer*);
    fmi2Status (*GetBoolean)(fmi2Component, const fmi2ValueReference*, size_t, fmi2Boolean*);
    fmi2Status (*GetString)(fmi2Component, const fmi2ValueReference*, size_t, fmi2String*);
    fmi2Status (*SetReal)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2Real*);
    fmi2Status (*SetInteger)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2Integer*);
    fmi2Status (*SetBoolean)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2Boolean*);
    fmi2Status (*SetString)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2String*);
    fmi2Status (*GetFMUstate)(fmi2Component, fmi2FMUstate*);
    fmi2Status (*SetFMUstate)(fmi2Component, fmi2FMUstate);
    fmi2Status (*FreeFMUstate)(fmi2Component, fmi2FMUstate*);
    fmi2Status (*SerializedFMUstateSize)(fmi2Component, fmi2FMUstate, size_t*);
    fmi2Status (*SerializeFMUstate)(fmi2Component, fmi2FMUstate, fmi2Byte*, size_t);
    fmi2Status (*DeSerializeFMUstate)(fmi2Component, const fmi2Byte*, size_t, fmi2FMUstate*);
    fmi2Status (*GetDirectionalDerivative)(fmi2Component, const fmi2ValueReference*, size_t,
                                           const fmi2ValueReference*, size_t, const fmi2Real*, fmi2Real*);
    fmi2Status (*SetRealInputDerivatives)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2Integer*,
                                          const fmi2Real*);
    fmi2Status (*GetRealOutputDerivatives)(fmi2Component, const fmi2ValueReference*, size_t, const fmi2Integer*,
                                           fmi2Real*);
    fmi2Status (*DoStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
    fmi2Status (*CancelStep)(fmi2Component);
    fmi2Status (*GetStatus)(fmi2Component, const fmi2StatusKind, fmi2Status*);
    fmi2Status (*GetRealStatus)(fmi2Component, const fmi2StatusKind, fmi2Real*);
    fmi2Status (*GetIntegerStatus)(fmi2Component, const fmi2StatusKind, fmi2Integer*);
    fmi2Status (*GetBooleanStatus)(fmi2Component, const fmi2StatusKind, fmi2Boolean*);
    fmi2Status (*GetStringStatus)(fmi2Component, const fmi2StatusKind, fmi2String*);
} Binary;

/* each entry of Binary, its symbol and its place */
static const struct { const char* name; size_t at; } FUNCTIONS[] = {
#define F(x) {"fmi2" #x, offsetof(Binary, x)}
    F(Instantiate), F(FreeInstance), F(SetupExperiment), F(EnterInitializationMode), F(ExitInitializationMode),
    F(Terminate), F(Reset), F(GetReal), F(GetInteger), F(GetBoolean), F(GetString), F(SetReal), F(SetInteger),
    F(SetBoolean), F(SetString), F(GetFMUstate), F(SetFMUstate), F(FreeFMUstate), F(SerializedFMUstateSize),
    F(SerializeFMUstate), F(DeSerializeFMUstate), F(GetDirectionalDerivative), F(SetRealInputDerivatives),
    F(GetRealOutputDerivatives), F(DoStep), F(CancelStep), F(GetStatus), F(GetRealStatus), F(GetIntegerStatus),
    F(GetBooleanStatus), F(GetStringStatus),
#undef F
};

/* ---- one instance --------------------------------------------------------------------------------------------- */
typedef struct {
    fmi2CallbackFunctions host; /* the host's callbacks, copied */
    fmi2CallbackFunctions own;  /* PythonFMU's: this library's logger, componentEnvironment this struct */
    void* library;              /* PythonFMU's binary (dlopen's reference) */
    Binary real;
    fmi2Component instance;     /* PythonFMU's instance */
    int logging_on;             /* what the host asked for (fmi2Instantiate, fmi2SetDebugLogging) */
    size_t n_categories;
    char** categories;
    int error_logged;           /* an fmi2Error (or fmi2Fatal) message during the current call */
} Shim;

#define SUFFIX "_pythonfmu.so" /* PythonFMU's binary: <this library's name less .so> + SUFFIX */

static void free_categories(Shim* s) {
    size_t i;
    for (i = 0; i < s->n_categories; i++) free(s->categories[i]);
    free(s->categories);
    s->categories = NULL;
    s->n_categories = 0;
}

static int passed_on(const Shim* s, fmi2String category) {
    size_t i;
    if (!s->logging_on) return 0;
    if (s->n_categories == 0) return 1;
    for (i = 0; i < s->n_categories; i++)
        if (strcmp(s->categories[i], category ? category : "") == 0) return 1;
    return 0;
}

/* PythonFMU's logger calls this with the message as the format and no arguments: passed on as it came */
static void shim_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                        fmi2String message, ...) {
    Shim* s = (Shim*)env;
    if (s == NULL) return;
    if (status >= fmi2Error) s->error_logged = 1;
    if (s->host.logger != NULL && passed_on(s, category))
        s->host.logger(s->host.componentEnvironment, name, status, category, message);
}

/* a message of this library's own, passed as PythonFMU passes its messages: as the format, with no arguments (FMPy
 * shows the format), so with no '%' in it */
static void say(const fmi2CallbackFunctions* f, fmi2String name, fmi2Status status, char* message) {
    char* p;
    for (p = message; *p; p++)
        if (*p == '%') *p = '_';
    if (f != NULL && f->logger != NULL) f->logger(f->componentEnvironment, name, status, "logStatusFatal", message);
}

/* the status of a call PythonFMU's binary returned `status` for: fmi2Error where it logged an fmi2Error message */
static fmi2Status refused(const Shim* s, fmi2Status status) {
    return (status == fmi2OK || status == fmi2Warning) && s->error_logged ? fmi2Error : status;
}

#define SHIM(c) ((Shim*)(c))
/* a call forwarded: the flag cleared, PythonFMU's function called, its status corrected */
#define FORWARD(c, fn, ...)                                                                                          \
    do {                                                                                                             \
        Shim* s_ = SHIM(c);                                                                                          \
        if (s_ == NULL) return fmi2Error;                                                                            \
        s_->error_logged = 0;                                                                                        \
        return refused(s_, s_->real.fn(s_->instance, __VA_ARGS__));                                                  \
    } while (0)
#define FORWARD0(c, fn)                                                                                              \
    do {                                                                                                             \
        Shim* s_ = SHIM(c);                                                                                          \
        if (s_ == NULL) return fmi2Error;                                                                            \
        s_->error_logged = 0;                                                                                        \
        return refused(s_, s_->real.fn(s_->instance));                                                               \
    } while (0)

/* ---- the FMI 2.0 functions ------------------------------------------------------------------------------------ */
EXPORT const char* fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char* fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions* functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    Dl_info self;
    char message[4400];
    char* path;
    size_t n, i;
    Shim* s;
    if (functions == NULL) return NULL;
    if (!dladdr((const void*)FUNCTIONS, &self) || self.dli_fname == NULL) {
        snprintf(message, sizeof message, "fmi2Instantiate: the FMU's binary cannot find its own path");
        say(functions, instanceName, fmi2Fatal, message);
        return NULL;
    }
    n = strlen(self.dli_fname);
    if (n > 3 && strcmp(self.dli_fname + n - 3, ".so") == 0) n -= 3;
    path = (char*)malloc(n + sizeof SUFFIX);
    s = (Shim*)calloc(1, sizeof(Shim));
    if (path == NULL || s == NULL) {
        free(path);
        free(s);
        snprintf(message, sizeof message, "fmi2Instantiate: out of memory");
        say(functions, instanceName, fmi2Fatal, message);
        return NULL;
    }
    memcpy(path, self.dli_fname, n);
    memcpy(path + n, SUFFIX, sizeof SUFFIX);
    s->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (s->library == NULL) {
        snprintf(message, sizeof message, "fmi2Instantiate: cannot load PythonFMU's binary %s (%s)", path,
                 dlerror());
        free(path);
        free(s);
        say(functions, instanceName, fmi2Fatal, message);
        return NULL;
    }
    for (i = 0; i < sizeof FUNCTIONS / sizeof FUNCTIONS[0]; i++) {
        void* f = dlsym(s->library, FUNCTIONS[i].name);
        if (f == NULL) {
            snprintf(message, sizeof message, "fmi2Instantiate: PythonFMU's binary %s has no %s", path,
                     FUNCTIONS[i].name);
            dlclose(s->library);
            free(path);
            free(s);
            say(functions, instanceName, fmi2Fatal, message);
            return NULL;
        }
        /* a function pointer from dlsym's object pointer (POSIX) */
        memcpy((char*)&s->real + FUNCTIONS[i].at, &f, sizeof f);
    }
    free(path);
    s->host = *functions;
    s->own = *functions;
    s->own.logger = shim_logger;
    s->own.componentEnvironment = s;
    s->logging_on = loggingOn != fmi2False;
    s->instance = s->real.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, &s->own, visible,
                                      fmi2True);
    if (s->instance == NULL) { /* PythonFMU's binary has said why (fmi2Fatal) */
        dlclose(s->library);
        free(s);
        return NULL;
    }
    return s;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Shim* s = SHIM(c);
    if (s == NULL) return;
    s->real.FreeInstance(s->instance);
    dlclose(s->library);
    free_categories(s);
    free(s);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                      const fmi2String categories[]) {
    Shim* s = SHIM(c);
    size_t i;
    if (s == NULL) return fmi2Error;
    free_categories(s);
    s->logging_on = loggingOn != fmi2False;
    if (nCategories > 0 && categories != NULL) {
        s->categories = (char**)calloc(nCategories, sizeof(char*));
        if (s->categories == NULL) return fmi2Error;
        for (i = 0; i < nCategories; i++) {
            size_t n = strlen(categories[i] ? categories[i] : "") + 1;
            s->categories[i] = (char*)malloc(n);
            if (s->categories[i] == NULL) {
                s->n_categories = i;
                free_categories(s);
                return fmi2Error;
            }
            memcpy(s->categories[i], categories[i] ? categories[i] : "", n);
        }
        s->n_categories = nCategories;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    FORWARD(c, SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD0(c, EnterInitializationMode); }

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD0(c, ExitInitializationMode); }

EXPORT fmi2Status fmi2Terminate(fmi2Component c) { FORWARD0(c, Terminate); }

EXPORT fmi2Status fmi2Reset(fmi2Component c) { FORWARD0(c, Reset); }

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    FORWARD(c, GetReal, vr, nvr, value);
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    FORWARD(c, GetInteger, vr, nvr, value);
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    FORWARD(c, GetBoolean, vr, nvr, value);
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    FORWARD(c, GetString, vr, nvr, value);
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    FORWARD(c, SetReal, vr, nvr, value);
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Integer value[]) {
    FORWARD(c, SetInteger, vr, nvr, value);
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean value[]) {
    FORWARD(c, SetBoolean, vr, nvr, value);
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String value[]) {
    FORWARD(c, SetString, vr, nvr, value);
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) { FORWARD(c, GetFMUstate, state); }

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) { FORWARD(c, SetFMUstate, state); }

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) { FORWARD(c, FreeFMUstate, state); }

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t* size) {
    FORWARD(c, SerializedFMUstateSize, state, size);
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serializedState[],
                                        size_t size) {
    FORWARD(c, SerializeFMUstate, state, serializedState, size);
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                          fmi2FMUstate* state) {
    FORWARD(c, DeSerializeFMUstate, serializedState, size, state);
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                               size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                               size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    FORWARD(c, GetDirectionalDerivative, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    FORWARD(c, SetRealInputDerivatives, vr, nvr, order, value);
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                               const fmi2Integer order[], fmi2Real value[]) {
    FORWARD(c, GetRealOutputDerivatives, vr, nvr, order, value);
}

/* a step: PythonFMU's status as it is (a step the slave refuses: fmi2Discard) */
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Shim* s = SHIM(c);
    if (s == NULL) return fmi2Error;
    s->error_logged = 0;
    return s->real.DoStep(s->instance, currentCommunicationPoint, communicationStepSize,
                          noSetFMUStatePriorToCurrentPoint);
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD0(c, CancelStep); }

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* value) {
    FORWARD(c, GetStatus, s, value);
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real* value) {
    FORWARD(c, GetRealStatus, s, value);
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer* value) {
    FORWARD(c, GetIntegerStatus, s, value);
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* value) {
    FORWARD(c, GetBooleanStatus, s, value);
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String* value) {
    FORWARD(c, GetStringStatus, s, value);
}
