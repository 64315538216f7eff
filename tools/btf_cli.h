/* btf_cli.h - subcommands of the `btf` tool; each lives in tools/cmd_NAME.c.
 * Each takes argv with argv[0] = the subcommand name and returns the exit code
 * (0 ok, 1 failure, 2 usage error). */
#ifndef BTF_CLI_H
#define BTF_CLI_H

/* BTF_CLI_DECLS: one line per subcommand */
int cmd_chart(int argc, char **argv);
int cmd_compress(int argc, char **argv);
int cmd_eval(int argc, char **argv);
int cmd_export_thesis(int argc, char **argv);
int cmd_gen(int argc, char **argv);
int cmd_gen_model(int argc, char **argv);
int cmd_import_thesis(int argc, char **argv);
int cmd_library(int argc, char **argv);
int cmd_lod(int argc, char **argv);
int cmd_render(int argc, char **argv);

#endif
