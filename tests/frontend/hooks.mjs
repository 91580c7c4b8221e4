// Module resolution for unit-testing the console's scripts under Node: the pages import
// by the server's URL paths (/static/..., /vendor/uplot/...); here those map onto the
// repository's files, and /static/vocabulary.js onto the module the Python test wrote
// from the server's definitions (EXOSTUDY_VOCABULARY).
import { pathToFileURL } from "node:url";

const FRONTEND = new URL("../../frontend/", import.meta.url);

export async function resolve(specifier, context, nextResolve) {
  if (specifier === "/static/vocabulary.js") {
    const file = process.env.EXOSTUDY_VOCABULARY;
    if (!file) throw new Error("EXOSTUDY_VOCABULARY: the vocabulary module's file is not set");
    return { url: pathToFileURL(file).href, shortCircuit: true };
  }
  if (specifier.startsWith("/static/")) {
    return { url: new URL(`.${specifier}`, FRONTEND).href, shortCircuit: true };
  }
  if (specifier.startsWith("/vendor/uplot/")) {
    return { url: new URL(`node_modules/uplot/dist/${specifier.slice(14)}`, FRONTEND).href, shortCircuit: true };
  }
  return nextResolve(specifier, context);
}
