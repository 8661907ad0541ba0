from hybrid_sysid.app import main

main()
