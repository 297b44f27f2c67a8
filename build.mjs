// The editor's front end bundled for anywidget: omniwidget/widget/static/editor.js and the
// modules it imports, made one ES module (static/editor.bundle.js) by esbuild.
//
// anywidget loads a widget's front end as one module from a string, so relative imports
// cannot be resolved in the browser: the bundle is built here, committed, and shipped in the
// wheel (nothing is built or downloaded at run time). omniwidget/widget/editor.py gives
// anywidget the bundle's path, so with ANYWIDGET_HMR=1 anywidget watches the file and
// reloads the front end in the open notebooks whenever `npm run watch` rebuilds it.
//
//   node build.mjs            write static/editor.bundle.js          (npm run build)
//   node build.mjs --watch    rebuild it on every change of a source (npm run watch)
//   node build.mjs --check    fail unless the committed bundle is what the sources build
//                             to, and the sources use nothing the bundle cannot take (npm run check)
//   --static DIR              the folder of the sources and the bundle (default: the package's)
//
// What the bundle cannot take, each a failed build naming the module: an import that is not
// a relative path to a .js file of the same folder (a package, a URL, a file elsewhere, a
// stylesheet), an import anywidget's page cannot resolve (a computed import() or require()),
// a name a module does not export, a syntax error, and anything esbuild warns of.

import { createHash } from "node:crypto";
import { readFileSync, writeFileSync } from "node:fs";
import { dirname, join, relative, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";

import * as esbuild from "esbuild";

const ROOT = dirname(fileURLToPath(import.meta.url));
const ENTRY = "editor.js";
export const BUNDLE = "editor.bundle.js";
// The browsers JupyterLab 4 supports: newer syntax in a source is an error, never rewritten.
const TARGET = "es2022";

/** The bundle's first lines: what it is, how to rebuild it, and the digest of its sources. */
function header(sources, digest) {
  return [
    `// ${BUNDLE}: ${ENTRY} and the modules it imports, one ES module for anywidget, built by esbuild`,
    "// from build.mjs at the repository's root (npm run build; npm run watch while developing).",
    "// Generated: edit the sources, never this file; tests/test_js.py fails when it is out of date.",
    `// sources: ${sources.join(" ")}`,
    `// sources sha256: ${digest}`,
    "",
  ].join("\n");
}

/**
 * The SHA-256 of the sources, each its file name, a NUL, its text and a NUL, in name order
 * (tests/test_js.py computes the same to tell a stale bundle without Node).
 */
export function sourcesDigest(dir, sources) {
  const hash = createHash("sha256");
  for (const name of [...sources].sort()) {
    hash.update(`${name}\0`);
    hash.update(readFileSync(join(dir, name)));
    hash.update("\0");
  }
  return hash.digest("hex");
}

/** A folder as the messages name it: from the repository's root when it is inside it. */
function shown(path) {
  const inside = relative(ROOT, path);
  return inside && !inside.startsWith("..") ? inside : path;
}

/** An esbuild plugin refusing every import but a relative path to a .js module of the same folder. */
function sameFolderModules(dir) {
  return {
    name: "same-folder-modules",
    setup(build) {
      build.onResolve({ filter: /.*/ }, (args) => {
        if (args.kind === "entry-point") return undefined;
        const path = resolve(args.resolveDir, args.path);
        const isRelative = args.path.startsWith("./") || args.path.startsWith("../");
        if (!isRelative || dirname(path) !== dir || !path.endsWith(".js")) {
          return { errors: [{ text: `"${args.path}" is not a .js module of ${shown(dir)}: the bundle takes only "./name.js" imports of its sources` }] };
        }
        if (args.kind !== "import-statement" && args.kind !== "dynamic-import") {
          return { errors: [{ text: `"${args.path}" is loaded by ${args.kind}: the sources are ES modules, imported with import` }] };
        }
        return undefined;
      });
    },
  };
}

/** The esbuild options of the bundle of the sources in `dir`, built in memory. */
function options(dir) {
  return {
    absWorkingDir: dir,
    entryPoints: [ENTRY],
    outfile: join(dir, BUNDLE),
    bundle: true,
    format: "esm",
    platform: "browser",
    target: TARGET,
    charset: "utf8",
    metafile: true,
    write: false,
    logLevel: "silent",
    plugins: [sameFolderModules(dir)],
  };
}

/** Each error or warning as `file:line:column: text`. */
function messages(items) {
  return items.map((m) => (m.location ? `${m.location.file}:${m.location.line}:${m.location.column}: ${m.text}` : m.text));
}

/**
 * What the build gave, or why it is not a bundle anywidget can load: warnings, more than one
 * output, an import left in it (a computed one esbuild cannot follow), no default export.
 */
function bundled(dir, result) {
  const problems = messages(result.warnings);
  if (result.outputFiles.length !== 1) {
    problems.push(`the build wrote ${result.outputFiles.length} files, not one module: ${result.outputFiles.map((f) => relative(dir, f.path)).join(", ")}`);
  }
  const [output] = Object.values(result.metafile.outputs);
  for (const left of output?.imports ?? []) problems.push(`an import left in the bundle: "${left.path}" (${left.kind})`);
  const code = result.outputFiles[0]?.text ?? "";
  for (const found of code.matchAll(/\b(import|require)\s*\(\s*[^"'`\s)]/g)) {
    const before = code.slice(0, found.index).split("\n");
    const module = before.findLast((line) => /^\/\/ \S+\.js$/.test(line))?.slice(3) ?? ENTRY;
    const line = code.split("\n")[before.length - 1].trim();
    problems.push(`${module}: a computed ${found[1]}() the bundle cannot resolve: ${line}`);
  }
  if (!output?.exports.includes("default")) problems.push(`${ENTRY} has no default export (anywidget's { render })`);
  if (problems.length > 0) return { problems };
  const sources = Object.keys(result.metafile.inputs).sort();
  return { text: header(sources, sourcesDigest(dir, sources)) + code };
}

/** Build the sources in `dir`: { text } of the bundle, or { problems } saying why not. */
export async function build(dir) {
  try {
    return bundled(dir, await esbuild.build(options(dir)));
  } catch (failure) {
    if (!failure.errors) throw failure;
    return { problems: messages([...failure.errors, ...failure.warnings]) };
  }
}

function report(problems) {
  console.error(`The editor's front end does not bundle:\n  ${problems.join("\n  ")}`);
}

async function write(dir) {
  const { text, problems } = await build(dir);
  if (problems) {
    report(problems);
    return false;
  }
  writeFileSync(join(dir, BUNDLE), text);
  console.log(`wrote ${shown(join(dir, BUNDLE))} (${Buffer.byteLength(text)} bytes)`);
  return true;
}

async function check(dir) {
  const { text, problems } = await build(dir);
  if (problems) {
    report(problems);
    return false;
  }
  const path = join(dir, BUNDLE);
  let committed = null;
  try {
    committed = readFileSync(path, "utf8");
  } catch {
    // no bundle: out of date
  }
  if (committed !== text) {
    console.error(`${shown(path)} is out of date with its sources: run npm run build`);
    return false;
  }
  console.log(`${shown(path)} is up to date`);
  return true;
}

/** Rebuild on every change of a source until stopped; a failed build is reported and the last bundle kept. */
async function watch(dir) {
  const rewrite = {
    name: "rewrite",
    setup(b) {
      b.onEnd((result) => {
        const { text, problems } = result.errors.length > 0 ? { problems: messages(result.errors) } : bundled(dir, result);
        if (problems) return report(problems);
        writeFileSync(join(dir, BUNDLE), text);
        console.log(`${new Date().toLocaleTimeString()} rebuilt ${shown(join(dir, BUNDLE))}`);
      });
    },
  };
  const base = options(dir);
  const context = await esbuild.context({ ...base, plugins: [...base.plugins, rewrite] });
  await context.watch();
  console.log(`watching ${shown(dir)} (Ctrl+C stops)`);
}

async function main() {
  const { values } = parseArgs({
    options: { watch: { type: "boolean" }, check: { type: "boolean" }, static: { type: "string" } },
  });
  const dir = resolve(values.static ?? join(ROOT, "omniwidget", "widget", "static"));
  if (values.watch) return watch(dir);
  const ok = values.check ? await check(dir) : await write(dir);
  process.exitCode = ok ? 0 : 1;
}

if (process.argv[1] && resolve(process.argv[1]) === fileURLToPath(import.meta.url)) await main();
