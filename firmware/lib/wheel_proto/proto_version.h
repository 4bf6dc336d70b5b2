// proto_version.h - wheel-board protocol version. Bump on any change of proto_messages.def,
// proto_codes.def or params.def that changes bytes on the wire; the host refuses a mismatch.
#ifndef PROTO_VERSION_H
#define PROTO_VERSION_H

#define PROTO_VERSION 4
#define FW_VERSION_MAJOR 1
#define FW_VERSION_MINOR 0

#endif  // PROTO_VERSION_H
