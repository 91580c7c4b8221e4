// ESLint rule `exostudy/api-client`: every use of the generated API client names an
// operation it has. The client (frontend/static/api_client.js) is written from the
// server's OpenAPI schema, so a route renamed or removed on the server, once the client
// is regenerated, becomes an error here in every page that still calls it.
//
// Checked: named imports from api_client.js, and member chains on a namespace import
// (`import * as api` or `await import(...)`) or on an imported namespace:
// `api.trials.start`, `trials.start`, `api.trials.start.url`.

const CLIENT = /(^|\/)api_client\.js$/;
// What an operation carries besides being called (frontend/static/api.js `operation`).
const MEMBERS = new Set(["url", "text", "method", "path", "operation"]);

// The client's names: { exports: Set, namespaces: Map<name, Set<operation>> }.
export function clientNames(client) {
  const namespaces = new Map();
  for (const [name, value] of Object.entries(client)) {
    const ops = Object.entries(value || {}).filter(([, v]) => typeof v === "function" && v.operation);
    if (ops.length) namespaces.set(name, new Set(ops.map(([k]) => k)));
  }
  return { exports: new Set(Object.keys(client)), namespaces };
}

export function apiClientRule(names) {
  return {
    meta: {
      type: "problem",
      docs: { description: "calls only operations the generated API client has" },
      schema: [],
    },
    create(context) {
      const modules = new Set(); // local names bound to the whole client
      const spaces = new Map(); // local name -> namespace it is bound to

      function bindPattern(pattern, node) {
        if (pattern.type === "Identifier") modules.add(pattern.name);
        else if (pattern.type === "ObjectPattern") {
          for (const p of pattern.properties) {
            if (p.type !== "Property" || p.key.type !== "Identifier" || p.value.type !== "Identifier") continue;
            bindName(p.key.name, p.value.name, node);
          }
        }
      }
      function bindName(imported, local, node) {
        if (!names.exports.has(imported)) {
          context.report({ node, message: `api_client.js has no export '${imported}' (regenerate it, or the route was renamed)` });
        } else if (names.namespaces.has(imported)) {
          spaces.set(local, imported);
        }
      }
      function name(member) {
        if (member.computed) return member.property.type === "Literal" ? String(member.property.value) : null;
        return member.property.name;
      }
      function checkOperation(space, member) {
        const op = name(member);
        if (op === null) {
          context.report({ node: member, message: `name the operation of api.${space} literally` });
          return;
        }
        if (!names.namespaces.get(space).has(op)) {
          context.report({ node: member.property, message: `api.${space} has no operation '${op}' (routes: backend/api/routes; regenerate api_client.js)` });
          return;
        }
        const outer = member.parent;
        if (outer && outer.type === "MemberExpression" && outer.object === member) {
          const prop = name(outer);
          if (prop === null || !MEMBERS.has(prop)) {
            context.report({ node: outer.property, message: `api.${space}.${op} has no member '${prop}'` });
          }
        }
      }

      return {
        ImportDeclaration(node) {
          if (!CLIENT.test(node.source.value)) return;
          for (const s of node.specifiers) {
            if (s.type === "ImportNamespaceSpecifier") modules.add(s.local.name);
            else if (s.type === "ImportSpecifier") bindName(s.imported.name, s.local.name, s);
            else context.report({ node: s, message: "api_client.js has no default export" });
          }
        },
        VariableDeclarator(node) {
          const init = node.init && node.init.type === "AwaitExpression" ? node.init.argument : null;
          if (init && init.type === "ImportExpression" && init.source.type === "Literal" && CLIENT.test(init.source.value)) {
            bindPattern(node.id, node);
          }
        },
        MemberExpression(node) {
          if (node.object.type !== "Identifier") return;
          const local = node.object.name;
          if (modules.has(local)) {
            const space = name(node);
            if (space === null) {
              context.report({ node, message: "name the api_client.js export literally" });
            } else if (!names.exports.has(space)) {
              context.report({ node: node.property, message: `api_client.js has no export '${space}' (regenerate it, or the route was renamed)` });
            } else if (names.namespaces.has(space) && node.parent.type === "MemberExpression" && node.parent.object === node) {
              checkOperation(space, node.parent);
            }
          } else if (spaces.has(local)) {
            checkOperation(spaces.get(local), node);
          }
        },
      };
    },
  };
}
