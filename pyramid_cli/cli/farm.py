"""``pyramid farm-template``: an Open Job Description job template running a command over frames."""

from __future__ import annotations

import click

from pyramid_cli.cli.group import collector_on
from pyramid_cli.core.errors import UsageError


@click.command("farm-template", context_settings={"ignore_unknown_options": True, "allow_interspersed_args": False})
@click.option("--frames", required=True, metavar="RANGE", help="The job's frames: 1001-1240, 1001-1240x2 or "
              "1001-1240:2 (every other frame), 1,5-9; written to the template ascending, as Open Job Description "
              "requires (1010-1001 becomes 1001-1010).")
@click.option("--chunk", type=click.IntRange(1), default=10, show_default=True,
              help="Frames per task, at most, whatever the range's shape (one process, one warm executor each; "
                   "OpenJD evens the sizes: 10 frames at 4 are tasks of 4, 3, 3).")
@click.option("--target-seconds", type=click.IntRange(1), help="Target task run time, for schedulers that adapt "
              "the chunk size to it (targetRuntimeSeconds).")
@click.option("--name", help="Job name (default: the command).")
@click.option("--executable", default="pyramid", show_default=True, help="The pyramid program on the workers.")
@click.option("-o", "--output", "out_path", default="-", show_default=True, type=click.Path(dir_okay=False),
              help="Where to write the template (- for standard output).")
@click.argument("command", nargs=-1, required=True, type=click.UNPROCESSED, metavar="-- COMMAND ARGS...")
@click.pass_context
def farm_template(ctx: click.Context, frames, chunk, target_seconds, name, executable, out_path, command) -> None:
    """Write an Open Job Description job template (AWS Deadline Cloud's format) running COMMAND over frames.

    Each task runs COMMAND on a chunk of frames with --frames CHUNK (an OpenJD range
    such as 1001-1007:2, which --frames reads with the same meaning); the template
    validates with `openjd check` and runs locally with `openjd run`. COMMAND is
    planned over all the frames when the template is written: what its tasks would
    refuse (a bad option, an output template giving two frames one file, frames
    outside the pattern's range) is refused now. --frames, --shard, --cluster and
    --chunk cannot be in COMMAND (farm-template sets the frames; the tasks are the split).

    \b
    Example:
      pyramid farm-template --frames 1001-1240 --chunk 20 -o blur.json -- \\
          blur --levels 4 --skip-existing '/shots/sh010/plate.####.exr' -o '/shots/sh010/soft.####.exr'
      pyramid farm-template --frames 1001-1240x2 --chunk 8 -o half.json -- \\
          apply 'quadratic *v g' '/shots/sh010/plate.####.exr' -o '/shots/sh010/half/{stem}_half{ext}'
      openjd check blur.json && openjd run blur.json
      deadline bundle submit ...   # a job bundle holding template.json
    """
    from pyramid_cli.run.farm import check_plan, dumps, job_template

    collector_on()

    template = job_template(list(command), frames, chunk=chunk, name=name, executable=executable,
                            target_seconds=target_seconds)
    root = ctx.find_root().command
    assert isinstance(root, click.Group), "farm-template is a subcommand of the pyramid group"
    sub = root.get_command(ctx, command[0])
    assert sub is not None, "job_template refused a command the group does not have"
    try:
        parsed = sub.make_context(command[0], list(command[1:]), parent=ctx)
    except click.ClickException as e:
        raise UsageError(f"the command after --: {e.format_message().splitlines()[0]}") from None
    check_plan(parsed.params["paths"], parsed.params.get("template"), frames)
    text = dumps(template)
    if out_path == "-":
        click.echo(text, nl=False)
        return
    from pyramid_cli.run.farm import write

    write(out_path, text)
    click.echo(f"wrote {out_path}", err=True)


__all__ = ['farm_template']
