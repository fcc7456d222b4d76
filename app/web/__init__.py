"""The web application: ``main.create_app``, security and headers, the audit log, the FHIR export and the
routers of ``api`` (parse, authorise, call the store and the job engines, answer)."""
