"""Fuzz the public API and the command line (issue 23): no raw traceback, no NaN or infinity in
any result or file (tests/fuzz_api_cases.py says what is checked; benchmarks/fuzz_api.py runs it
longer)."""

from hypothesis import HealthCheck, event, given, settings

from fuzz_api_cases import cli_argv, function_call, program, run_cli, run_function, run_program

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
                derandomize=True)


@settings(max_examples=300, **SETTINGS)
@given(program())
def test_builder_programs_build_move_and_solve_or_name_the_problem(calls):
    event(run_program(calls))


@settings(max_examples=300, **SETTINGS)
@given(function_call())
def test_public_functions_return_finite_numbers_or_name_the_problem(call):
    name, kw = call
    event(f"{name}: {run_function(name, kw)}")


@settings(max_examples=60, **SETTINGS)
@given(cli_argv())
def test_command_line_options_exit_with_a_status_and_write_no_nan(argv):
    event(f"{argv[0]}: exit {run_cli(argv)}")
