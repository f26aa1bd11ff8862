from tactile_studio.cli import main

raise SystemExit(main())
