"""What a run says (pyramid_cli.run.report): which lines reach which stream, under -q and -v."""

from types import SimpleNamespace

from pyramid_cli.run.report import Reporter, announce_compiles, wrote_line


def recording(**kw):
    out, err = [], []
    return Reporter(out=out.append, err=err.append, **kw), out, err


def test_wrote_line():
    assert wrote_line("a.exr", 4, 3, None, "cpu") == "wrote a.exr (4×3, cpu)"
    assert wrote_line("a.tx", 4, 3, 3, "gl") == "wrote a.tx (4×3, 3 MIP levels, gl)"


def test_results_on_stdout_and_the_rest_on_stderr_with_their_prefixes():
    r, out, err = recording(verbose=True, interactive=True)
    r.result("wrote a.exr")
    r.warn("careful")
    r.detail("executor cpu")
    r.say("3 written")
    r.error("broken")
    r.notice("compiling")
    assert out == ["wrote a.exr"]
    assert err == ["pyramid: warning: careful", "pyramid: executor cpu", "pyramid: 3 written", "pyramid: error: broken",
                   "pyramid: compiling"]


def test_quiet_keeps_only_errors_and_details_need_verbose():
    r, out, err = recording(quiet=True, verbose=False, interactive=True)
    for say in (r.result, r.warn, r.detail, r.say, r.notice, r.error):
        say("x")
    assert out == [] and err == ["pyramid: error: x"]
    r, out, err = recording()
    r.notice("only at a terminal")
    r.detail("only under -v")
    assert out == err == []


def test_compiles_are_announced_at_a_terminal_only_when_there_are_some():
    def session(n):
        return SimpleNamespace(uncached=lambda work, images: n)

    r, _, err = recording(interactive=True)
    announce_compiles(session(5), None, [], r)
    assert err == ["pyramid: compiling 5 CPU kernel(s) for this machine, once (about 4 s; later runs load them from "
                   "the cache in a fraction of a second)"]
    for n, kw in ((0, {"interactive": True}), (5, {}), (5, {"interactive": True, "quiet": True})):
        r, _, err = recording(**kw)
        announce_compiles(session(n), None, [], r)
        assert err == []
