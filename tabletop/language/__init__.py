"""Language to robot code: the offline instruction parser (grammar in ``parser``, plan values
in ``plan``, code generation in ``codegen``), an LLM backend, and the sandbox that runs the code
against the robot API.

Typical use::

    from tabletop.language import instruction_to_code, run_instruction

    print(instruction_to_code("go to the mug near the sound of a dog barking"))
    run = run_instruction("move to the left of the red mug, then 5 cm north", robot, dry_run=True)
    run.targets                                        # (K, 3) [m], nothing moved
"""

from tabletop.language.codegen import instruction_to_code, plan_to_code
from tabletop.language.errors import (
    CodeRejected,
    LanguageError,
    LLMError,
    ParseError,
    SandboxError,
    SandboxLimit,
)
from tabletop.language.run import (
    BACKENDS,
    InstructionRun,
    Motion,
    TracingRobot,
    generate_code,
    run_instruction,
)
from tabletop.language.sandbox import (
    ROBOT_METHODS,
    ROBOT_MOVES,
    CallRecord,
    CheckedCode,
    SandboxConfig,
    SandboxRun,
    check_code,
    run_code,
)
from tabletop.reader.plan import (
    Above,
    BackAndForth,
    Between,
    Compass,
    Goal,
    GoTo,
    Part,
    Side,
    Step,
)
from tabletop.reader.rules import parse_instruction

__all__ = [
    "BACKENDS",
    "ROBOT_METHODS",
    "ROBOT_MOVES",
    "Above",
    "BackAndForth",
    "Between",
    "CallRecord",
    "CheckedCode",
    "CodeRejected",
    "Compass",
    "GoTo",
    "Goal",
    "InstructionRun",
    "LLMError",
    "LanguageError",
    "Motion",
    "ParseError",
    "Part",
    "SandboxConfig",
    "SandboxError",
    "SandboxLimit",
    "SandboxRun",
    "Side",
    "Step",
    "TracingRobot",
    "check_code",
    "generate_code",
    "instruction_to_code",
    "parse_instruction",
    "plan_to_code",
    "run_code",
    "run_instruction",
]
