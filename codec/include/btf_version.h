/* btf_version.h - the project's one version string, shared by `btf --version`,
 * `btfd --version`, btfd's hello message and btfcodec.pc (the Makefile reads
 * the BTF_VERSION line). Change it here only. */
#ifndef BTF_VERSION_H
#define BTF_VERSION_H

#define BTF_VERSION "0.4.0"

#endif
