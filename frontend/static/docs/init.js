// Starts Swagger UI on /docs from the locally installed swagger-ui-dist (no CDN, and
// no inline script, so the page keeps the app's Content-Security-Policy).
window.addEventListener("load", () => {
  window.ui = window.SwaggerUIBundle({
    url: "/openapi.json",
    dom_id: "#swagger-ui",
    presets: [window.SwaggerUIBundle.presets.apis],
    layout: "BaseLayout",
    deepLinking: true,
    // Requests from the page carry the session cookie; changes need the CSRF header.
    requestInterceptor: (req) => {
      const m = document.cookie.match(/(?:^|; )exostudy_csrf=([^;]+)/);
      if (m) req.headers["X-CSRF-Token"] = decodeURIComponent(m[1]);
      return req;
    },
  });
});
