"""What a gmsh .geo script may say: an allow-list of geometry and meshing statements.

A script is accepted (without ``--trust-geo``) only when every name in it is one of:

* a statement or function of the geometry and meshing part of the gmsh language
  (``STATEMENTS``, ``FUNCTIONS``), e.g. ``Point``, ``Line``, ``Plane Surface``, ``Physical
  Curve``, ``Transfinite``, ``Field``, ``For``/``EndFor``, ``Sqrt``;
* an option of ``Mesh.`` or ``Geometry.`` in ``OPTIONS``, or a mesh-size field of a type in
  ``FIELD_TYPES`` with options in ``FIELD_OPTIONS``;
* a variable the script assigns before it uses it (``lc = 0.1;``, ``For i In ...``).

Anything else (``SystemCall``, ``Include``, ``Merge``, ``General.*`` options, ``Field`` types
that run programs or read files, string-to-name conversions, ...) is refused with its line,
whatever it is: gmsh keeps adding statements, and an unknown one is never assumed harmless.
Comments are skipped and string literals are not read as names (they name physical groups);
the check is one linear pass over the text. It is one of two walls: the script is also meshed
in a limited child process (:mod:`critfric.meshing.sandbox`).
"""

from __future__ import annotations

import bisect
import re

STATEMENTS = frozenset(["Point", "Line", "Circle", "Ellipse", "Spline", "BSpline", "Bezier", "Curve", "Loop", "Surface", "Plane", "Physical", "Transfinite", "Recombine", "Characteristic", "Length", "MeshSize", "Mesh", "Field", "Background", "Coherence", "Delete", "Compound", "Translate", "Rotate", "Symmetry", "Dilate", "Duplicata", "Extrude", "Layers", "Recombine", "Boundary", "CombinedBoundary", "For", "In", "EndFor", "If", "ElseIf", "Else", "EndIf", "Using", "Progression", "Bump", "Beta", "Left", "Right", "Alternate", "AlternateLeft", "AlternateRight", "Smoothing", "Reverse", "Reverse", "Rectangle", "Disk", "Circle", "BooleanUnion", "BooleanDifference", "BooleanIntersection", "BooleanFragments", "SetFactory", "Hide", "Show", "Geometry", "Color", "Macro", "Function", "Call", "Return", "Volume", "Box", "Block", "Sphere", "Cylinder", "Cone", "Torus", "Wedge", "Ellipsoid", "Ellipsis", "CatmullRom", "Nurbs", "Knots", "Order", "Ruled", "ThruSections", "ThickSolid", "Wire", "Fillet", "Chamfer", "Affine", "Periodic", "Recursive"])
FUNCTIONS = frozenset(["Sqrt", "Sin", "Cos", "Tan", "Asin", "Acos", "Atan", "Atan2", "Sinh", "Cosh", "Tanh", "Exp", "Log", "Log10", "Fabs", "Abs", "Floor", "Ceil", "Round", "Fmod", "Modulo", "Hypot", "Rand", "Min", "Max", "Pi", "Sign", "Step", "ArcCos", "ArcSin", "ArcTan", "ArcTan2", "LinSpace", "LogSpace", "newp", "newl", "news", "newll", "newc", "newreg", "newf", "newcl", "newsl", "newv", "newvl"])
OPTIONS = {
    "Mesh": frozenset(["CharacteristicLengthMax", "CharacteristicLengthMin", "CharacteristicLengthFactor", "CharacteristicLengthFromPoints", "CharacteristicLengthFromCurvature", "CharacteristicLengthExtendFromBoundary", "MeshSizeMax", "MeshSizeMin", "MeshSizeFactor", "MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary", "MeshSizeFromParametricPoints", "Algorithm", "RecombineAll", "RecombinationAlgorithm", "Smoothing", "ElementOrder", "SecondOrderLinear", "SecondOrderIncomplete", "Optimize", "OptimizeNetgen", "OptimizeThreshold", "RandomFactor", "RandomSeed", "AngleToleranceFacetOverlap", "SubdivisionAlgorithm", "TransfiniteTri", "MinimumCirclePoints", "MinimumCurvePoints"]),
    "Geometry": frozenset(["Tolerance", "ToleranceBoolean", "AutoCoherence", "OCCBooleanPreserveNumbering", "MatchMeshTolerance"]),
}
FIELD_TYPES = frozenset(["Distance", "Threshold", "MathEval", "MathEvalAniso", "Box", "Ball", "Cylinder", "Frustum", "Min", "Max", "Constant", "Restrict", "Param", "Gradient", "Mean", "Laplacian", "Curvature", "AttractorAnisoCurve", "BoundaryLayer"])
FIELD_OPTIONS = frozenset(["PointsList", "CurvesList", "EdgesList", "SurfacesList", "FacesList", "NodesList", "NumPointsPerCurve", "Sampling", "InField", "FieldsList", "FieldX", "FieldY", "FieldZ", "SizeMin", "SizeMax", "DistMin", "DistMax", "LcMin", "LcMax", "Sigmoid", "StopAtDistMax", "F", "M11", "M12", "M13", "M22", "M23", "M33", "VIn", "VOut", "XMin", "XMax", "YMin", "YMax", "ZMin", "ZMax", "Thickness", "XCenter", "YCenter", "ZCenter", "XAxis", "YAxis", "ZAxis", "Radius", "InnerRadius", "R1", "R2", "R1_inner", "R2_inner", "Z1", "Z2", "X1", "X2", "Y1", "Y2", "Value", "IncludeBoundary", "Kind", "Delta", "Size", "SizeFar", "Ratio", "Thickness", "hwall_n", "hfar", "IncludeVolumes"])

# as gmsh's lexer: a string runs to the next quote of its kind, line breaks included, and
# knows no escapes; a comment to the end of its line or to */
_LEXER = re.compile(
    r"(?P<comment>//[^\n]*|/\*.*?(?:\*/|\Z))"
    r"""|(?P<string>"[^"]*"?|'[^']*'?)"""
    r"|(?P<num>\d+\.\d*(?:[Ee][-+]?\d+)?|\d*\.\d+(?:[Ee][-+]?\d+)?|\d+[Ee][-+]?\d+|\d+)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<space>\s+)|(?P<other>.)", re.DOTALL | re.ASCII)


#: gmsh's own words, never a variable (a name "assigned" where gmsh does not parse, e.g. in
#: ``If (0) ... EndIf``, would otherwise pass as one): the keywords of gmsh's lexer
#: (src/parser/Gmsh.l) and the command names its grammar compares (src/parser/Gmsh.y), gmsh 4.15
RESERVED = frozenset("""
    Abort Abs AbsolutePath Acos AdaptMesh Affine Alias AliasWithOptions All AlternateLeft
    AlternateRight Append ArcCos ArcSin ArcTan ArcTan2 Asin Atan Atan2 BSpline Background
    Beta Beta_HWall Beta_Symmetrical Beta_Symmetrical_HWall Betti Bezier Block
    BooleanCoherence BooleanCommon BooleanCut BooleanDifference BooleanFragments
    BooleanFuse BooleanIntersection BooleanSection BooleanUnion BoundaryLayer BoundingBox
    Box Bump Bump_HWall Call Catenary CatmullRom Ceil CenterOfMass Chamfer Characteristic
    Circle ClassifySurfaces Closest CodeName Coherence Cohomology Color ColorTable Combine
    Compound Cone Coordinates CopyOptions Cos Cosh Cpu Crack CreateDir CreateGeometry
    CreateMeshEdges CreateMeshFaces CreateOverlaps CreateTopology CurrentDir
    CurrentDirectory CurrentFileName Curvature Curve Cut CutMesh CutMeshTri Cylinder
    DefineConstant DefineNumber DefineString Degenerated Delete Dilate DimNameSpace
    DirName Disk Draw ElementsByViewName ElementsFromAllViews ElementsFromVisibleViews
    Ellipse Ellipsis Ellipsoid Elliptic Else ElseIf Embedded Empty EndFor EndIf Error
    Euclidean Euclidian Exists Exit Exp Extrude Fabs Field FileExists Fillet Find
    FixRelativePath Floor Fmod For Function GMSH_MAJOR_VERSION GMSH_MINOR_VERSION
    GMSH_PATCH_VERSION GeoEntity Geometry GetEnv GetForced GetForcedStr GetNumber
    GetString GetStringValue GetValue GmshExecutableName HealShapes Hide Hole Homology
    Hypot INTERPOLATION_SCHEME If In Include Index Intersect Intersection Knots Layers
    Left Length Levelset LinSpace Line List ListFromFile Log Log10 LogSpace LowerCase
    LowerCaseIn MPI_Rank MPI_Size Macro Mass MathEval MatrixOfInertia Max Memory Merge
    MergeWithBoundingBox Mesh MeshAlgorithm MeshSize MeshSizeFromBoundary Meshes Min Model
    Modulo N2S NameStruct NameToString NewModel NonBlockingSystemCall Normal Nurbs
    OnelabAction OnelabRun OptimizeMesh Options Order Parametric Parent PartitionMesh
    Periodic Physical Physicals Pi Plane Plugin Point PolarSphere PostView Power Print
    Printf Progression Progression_HWall QuadTriAddVerts QuadTriAddverts QuadTriNoNewVerts
    QuadTriNoNewverts QuadTriNonewVerts QuadTriNonewverts QuadTriaddVerts QuadTriaddverts
    QuadTrinoNewVerts QuadTrinoNewverts QuadTrinonewVerts QuadTrinonewverts Quadric
    QuadtriAddVerts QuadtriAddverts QuadtriNoNewVerts QuadtriNoNewverts QuadtriNonewVerts
    QuadtriNonewverts QuadtriaddVerts Quadtriaddverts QuadtrinoNewVerts QuadtrinoNewverts
    QuadtrinonewVerts Quadtrinonewverts Rand RecombLaterals Recombine RecombineMesh
    Recomblaterals Rectangle Recursive RefineMesh RelocateMesh Remesh RenumberMeshElements
    RenumberMeshNodes ReorientMesh Return Reverse ReverseMesh Right Rotate Round Ruled S2N
    Save ScaleLastLayer SendToServer SetChanged SetCurrentWindow SetFactory SetMaxTag
    SetName SetNumber SetOrder SetPartition SetString SetTag Sewing ShapeFromFile Show Sin
    Sinh Sleep Slide Smoother Sphere Spline Split SplitCurrentWindowHorizontal
    SplitCurrentWindowVertical SplitMesh Sprintf Sqrt Step Str StrCat StrChoice StrCmp
    StrFind StrLen StrPrefix StrRelative StrReplace StrSub StringToName Struct Surface
    Symmetry SyncModel System SystemCall T2 T3 TIME Tan Tanh TestLevel TextAttributes
    ThickSolid ThruSections TimeSteps TimeStepsByViewName TimeStepsFromAllViews
    TimeStepsFromVisibleViews Today Torus TotalMemory TransfQuadTri TransfQuadtri
    Transfinite TransformMesh TransfquadTri Transfquadtri Translate UndefineConstant Union
    Unique UnsplitWindow UpperCase Using Variables View Views Volume Warning Wedge Wire
    all
""".split())  # noqa: SIM905 (a word list)
# gmsh's lexer cuts a string at 1023 bytes and reads the rest as code, and gmsh formats its
# messages (an unknown variable, a command) into 1024-byte buffers on the stack, unchecked:
# names and strings are kept well below (the longest in gmsh's tutorials: 22 and 109)
MAX_STRING, MAX_NAME = 256, 128
MAX_INDEX_GROUPS = 4  # name~{i}~{j}...: each group adds up to 12 bytes ("_-2147483648")
# gmsh skips a block it does not run (If, For, Macro) with a scanner of its own, which at each
# E, I, F or R (the first letters of If, EndIf, Else, ElseIf, For, EndFor, Return) reads on
# raw characters: the one right after such a letter is lost when no word matches, and the
# four after a nested If or For are taken whole. A quote or a / there would start or end a
# string or comment where this check does not: refused.
SKIP_LETTERS = "EIFR"
SKIP_WORDS, SKIP_WINDOW = ("If", "For"), 4
UNSAFE_NEAR_SKIP = "\"'/"


_RUNS = "runs a shell command"
_READS = "reads another file (a .py file would be run)"
#: what some refused names do (for the message; the refusal does not depend on this list)
KNOWN = {
    "SystemCall": _RUNS, "NonBlockingSystemCall": _RUNS, "System": _RUNS,
    "OnelabRun": "runs an external program (ONELAB client)",
    "Solver": "configures an external solver program", "Plugin": "runs a gmsh plugin",
    "Include": "reads and runs another script", "Merge": _READS, "MergeWithBoundingBox": _READS,
    "ShapeFromFile": "reads a CAD file", "ListFromFile": "reads another file",
    "Save": "writes a file", "Print": "writes a file", "CreateDir": "creates a directory",
    "SendToServer": "sends data to another program", "General": "sets gmsh's own options "
    "(log files, terminal output, abort on error)",
    "StringToName": "makes a command name from a string (it can hide any command)",
    "S2N": "makes a command name from a string (it can hide any command)",
    "Exit": "ends the program running it (critfric itself)", "Sleep": "pauses the program",
    "Printf": "prints (nothing critfric shows), through a format gmsh does not check: a "
    "long one overflows its buffers",
}


def _tokens(text: str):
    """(kind, value, offset) of every token but comments and white space."""
    for m in _LEXER.finditer(text):
        kind = m.lastgroup
        if kind not in ("comment", "space"):
            yield kind, m.group(), m.start()


def refusals(text: str) -> list[tuple[int, str, str]]:
    """(line, name, why) for every name of a .geo script outside the allow-list."""
    text = text.removeprefix("\ufeff")  # a UTF-8 byte-order mark is not a statement
    newlines = [m.start() for m in re.finditer("\n", text)]
    tokens = list(_tokens(text))
    defined: set[str] = set()
    found: list[tuple[int, str, str]] = []

    def refuse(offset: int, word: str, why: str) -> None:
        if offset not in seen:
            seen.add(offset)
            found.append((bisect.bisect_right(newlines, offset) + 1, word, why))

    seen: set[int] = set()
    field_options: set[int] = set()  # token indices of Field[...].<option> names

    if "\0" in text:  # gmsh ends a string or comment there and reads on as statements
        refuse(text.index("\0"), "NUL", "a NUL character (not text)")
    bare = re.search("\r(?!\n)", text)  # gmsh's reader ends a line there, a // comment not
    if bare:
        refuse(bare.start(), "CR", "a carriage return without a line feed")
    for i, (kind, value, offset) in enumerate(tokens):
        if kind == "other" and value in "$@\\`":
            refuse(offset, value, "not part of the geometry language")
        if kind == "string" and (len(value) < 2 or value[-1] != value[0]):
            refuse(offset, value[:1], "a string that is not closed")
        elif kind == "string" and len(value[1:-1].encode()) > MAX_STRING:
            refuse(offset, value[:1], f"a string of more than {MAX_STRING} bytes")
        if kind == "name":
            end = offset + len(value)
            window = text[end:end + (SKIP_WINDOW if value in SKIP_WORDS else 1)]
            if value[-1] in SKIP_LETTERS and text[end:end + 1] in tuple(UNSAFE_NEAR_SKIP) \
                    or value in SKIP_WORDS and any(c in UNSAFE_NEAR_SKIP for c in window):
                refuse(end, f"{value}{window}", "a quote or / right after a word where gmsh "
                       "skipping a block reads the characters raw (add a space)")
        if kind != "name":
            continue
        if len(value) > MAX_NAME:
            refuse(offset, value[:20] + "...", f"a name of more than {MAX_NAME} characters")
            continue
        groups, j = 0, i + 1  # name~{a}~{b}...: gmsh builds name_a_b... (no other way grows one)
        while j + 1 < len(tokens) and tokens[j][1] == "~" and tokens[j + 1][1] == "{":
            depth, j, groups = 0, j + 1, groups + 1
            while j < len(tokens):
                depth += {"{": 1, "}": -1}.get(tokens[j][1], 0)
                j += 1
                if depth == 0:
                    break
        if groups > MAX_INDEX_GROUPS:
            refuse(offset, value + "~{...}", f"a name with more than {MAX_INDEX_GROUPS} ~{{}} "
                   "indices (gmsh quotes the name it builds in a 1024-byte buffer)")
        before = tokens[i - 1][1] if i else ""
        after = tokens[i + 1][1] if i + 1 < len(tokens) else ""
        if before == "." and (i in field_options or i >= 2 and tokens[i - 2][1] in OPTIONS):
            continue  # an option (Mesh.X) or field option (Field[1].X): checked with its owner
        if before == ".":
            refuse(offset, value, "an option of a category critfric does not allow")
            continue
        if value in OPTIONS:
            if after == ".":
                option = tokens[i + 2][1] if i + 2 < len(tokens) else ""
                if option not in OPTIONS[value]:
                    refuse(offset, f"{value}.{option}", "an option outside the meshing "
                           "options critfric allows")
                continue
            if value in STATEMENTS:  # "Geometry" / "Mesh" used as a statement word
                continue
        if value == "Field" and after == "[":
            j = i + 2  # Field[expr] = Type;  or  Field[expr].Option = value;
            depth = 1
            while j < len(tokens) and depth:
                depth += {"[": 1, "]": -1}.get(tokens[j][1], 0)
                j += 1
            nxt = tokens[j][1] if j < len(tokens) else ""
            if nxt == "=" and j + 1 < len(tokens):
                ftype = tokens[j + 1][1]
                if tokens[j + 1][0] != "name" or ftype not in FIELD_TYPES:
                    refuse(tokens[j + 1][2], ftype, "a mesh-size field type critfric does "
                           "not allow (it may run a program or read a file)")
            elif nxt == "." and j + 1 < len(tokens):
                option = tokens[j + 1][1]
                field_options.add(j + 1)
                if option not in FIELD_OPTIONS:
                    refuse(tokens[j + 1][2], option, "a field option critfric does not allow")
            continue
        if i >= 2 and tokens[i - 1][1] == "=" and tokens[i - 2][1] == "]" \
                and value in FIELD_TYPES:
            continue  # the type of a field, checked above
        if value in KNOWN:  # refused where first met, so never defined
            refuse(offset, value, KNOWN[value])
            continue
        if value in STATEMENTS or value in FUNCTIONS or value in defined:
            if before in ("Function", "Macro"):
                defined.add(value)
            continue
        # a variable or macro: defined by `name =`, `name[] =`, `name(...) =`, `name += ...`,
        # `For name`, `Macro name`; never one of gmsh's own words
        if before in ("Function", "Macro", "For") or after in (
                "=", "[", "(", "+", "-", "*", "/", "~") and _assigns(tokens, i):
            if value in RESERVED:
                refuse(offset, value, "a word of the gmsh language, not a variable")
            else:
                defined.add(value)
            continue
        refuse(offset, value, "not a geometry or meshing statement critfric allows, nor a "
               "variable assigned before")
    return found + _jump_refusals(text, tokens, newlines)


def _assigns(tokens, i: int) -> bool:
    """Whether tokens[i] (a name) starts an assignment: name = / name[...] = / name~{...} =
    / name += ..."""
    j = i + 1
    while j + 1 < len(tokens) and tokens[j][1] == "~" and tokens[j + 1][1] == "{":
        depth, j = 0, j + 1
        while j < len(tokens):
            depth += {"{": 1, "}": -1}.get(tokens[j][1], 0)
            j += 1
            if depth == 0:
                break
    if j < len(tokens) and tokens[j][1] in "[(":
        close, depth = {"[": "]", "(": ")"}[tokens[j][1]], 0
        while j < len(tokens):
            depth += {tokens[i + 1][1]: 1, close: -1}.get(tokens[j][1], 0)
            j += 1
            if depth == 0:
                break
    if j < len(tokens) and tokens[j][1] in "+-*/" and j + 1 < len(tokens) \
            and tokens[j + 1][1] == "=":
        return True
    return j < len(tokens) and tokens[j][1] == "=" and (
        j + 1 >= len(tokens) or tokens[j + 1][1] != "=")


MAX_JUMP_LINE = 4000  # gmsh reads a line in chunks of 8192 bytes or more
JUMPS = ("For", "EndFor", "Macro", "Function", "Call", "Return")


def _jump_refusals(text: str, tokens: list, newlines: list[int]
                   ) -> list[tuple[int, str, str]]:
    """gmsh reads a script a line at a time; a For header and a Macro (Function) name keep
    where the next line starts, and EndFor, Call and Return jump back there, or to the line
    after the Call, without dropping the rest of the line being read: that rest is read
    before another line than in the file (a /* comment or a string then spans other text, a
    statement gets other words). So each of them must end its line (a // comment may follow),
    on a line short enough to be read whole. ``newlines``: the offsets of the line breaks."""
    found = []
    after = "text after it on its line (gmsh re-reads lines there: put it at the end of its line)"
    long = f"on a line of more than {MAX_JUMP_LINE} bytes (gmsh reads such a line in pieces)"

    def line(at: int) -> tuple[int, int]:
        stop = text.find("\n", at)
        return text.rfind("\n", 0, at) + 1, len(text) if stop < 0 else stop

    for i, (kind, value, offset) in enumerate(tokens):
        if kind != "name" or value not in JUMPS:
            continue
        j = i  # the construct's last token: For's closing bracket, the name, Call's ';'
        if value in ("Macro", "Function"):
            j = i + 1
        elif value in ("For", "Call"):
            depth, j = 0, i + 1
            while j < len(tokens):
                word = tokens[j][1]
                depth += {"(": 1, "{": 1, ")": -1, "}": -1}.get(word, 0)
                if (value == "Call" and word == ";" or value == "For" and depth == 0
                        and word in ")}"):
                    break
                j += 1
        if j >= len(tokens):
            continue  # gmsh refuses the unfinished construct itself
        end = tokens[j][2] + len(tokens[j][1])
        rest = text[end:line(end)[1]].lstrip(" \t\r\f")
        line_no = bisect.bisect_right(newlines, offset) + 1
        if rest and not rest.startswith("//"):
            found.append((line_no, value, after))
        start, stop = line(offset)
        if len(text[start:max(stop, line(end)[1])].encode()) > MAX_JUMP_LINE:
            found.append((line_no, value, long))
    return found
