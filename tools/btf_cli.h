/* btf_cli.h - subcommands of the `btf` tool; each lives in tools/cmd_NAME.c.
 * Each takes argv with argv[0] = the subcommand name and returns the exit code
 * (0 ok, 1 failure, 2 usage error). */
#ifndef BTF_CLI_H
#define BTF_CLI_H

/* BTF_CLI_DECLS: one line per subcommand */

#endif
